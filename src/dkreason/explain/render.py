"""An explanation as text (the CLI's), JSON (stable, for tools) and Graphviz dot."""

from __future__ import annotations

import itertools

from ..datalog import Rule
from .explanation import Explanation
from .replay import Failure, Proof


def _rule_ref(rule: Rule | None) -> str:
    return str(rule.span) if rule else ""


def proof_json(p: Proof) -> dict[str, object]:
    out: dict[str, object] = {"fact": p.text, "atom": list(p.fact)}
    if p.rule:
        out["rule"] = _rule_ref(p.rule)
        out["rule_text"] = p.rule.text
    if p.source:
        out["source"] = p.source
    if p.children:
        out["children"] = [proof_json(c) for c in p.children]
    return out


def failure_json(f: Failure) -> dict[str, object]:
    out: dict[str, object] = {"goal": f.text, "failed": f.condition_text, "negated": f.negated}
    if f.rule:
        out["rule"] = _rule_ref(f.rule)
    if f.nearby:
        out["nearby"] = list(f.nearby)
    if isinstance(f.because, Failure):
        out["because"] = failure_json(f.because)
    elif isinstance(f.because, Proof):
        out["because"] = proof_json(f.because)
    return out


def to_json(e: Explanation) -> dict[str, object]:
    return {
        "formula": e.formula,
        "features": [
            {
                "feature": f.feature,
                "why": [
                    {
                        "platform": w.platform,
                        "topic": w.topic,
                        "filter": dict(w.filter),
                        "summary": list(w.summary),
                        "proof": proof_json(w.proof),
                    }
                    for w in f.why
                ],
                "why_not": [
                    {
                        "platform": n.platform,
                        "topic": n.topic,
                        "reason": n.reason,
                        "trace": failure_json(n.trace),
                    }
                    for n in f.why_not
                ],
            }
            for f in e.features
        ],
    }


def to_text(e: Explanation) -> str:
    lines: list[str] = []
    for f in e.features:
        lines.append(f.feature)
        for w in f.why:
            ids = ", ".join(f"{k} = {v}" for k, v in w.filter)
            lines.append(f"  ✔ {w.topic} on {w.platform}" + (f" ({ids})" if ids else ""))
            lines += [f"      {s}" for s in w.summary]
            lines.append("      proof:")
            _proof_lines(w.proof, 8, lines)
        for n in f.why_not:
            lines.append(f"  ✘ {n.topic or 'no topic'} on {n.platform}: {n.reason}")
            lines.append("      trace:")
            _failure_lines(n.trace, 8, lines)
        if not f.why and not f.why_not:
            lines.append("  (no topic, and no platform to look on)")
    return "\n".join(lines)


def _proof_lines(p: Proof, indent: int, out: list[str]) -> None:
    where = f"  [{_rule_ref(p.rule)}]" if p.rule else f"  ← {p.source}" if p.source else ""
    out.append(" " * indent + p.text + where)
    for c in p.children:
        _proof_lines(c, indent + 2, out)


def _failure_lines(f: Failure, indent: int, out: list[str]) -> None:
    pad = " " * indent
    rule = f"  [{_rule_ref(f.rule)}]" if f.rule else ""
    verb = "holds" if f.negated else "fails"
    out.append(
        f"{pad}{f.text}: {'' if f.negated else 'no '}{f.condition_text}"
        f"{' (which excludes it)' if f.negated else ''}{rule}".replace(
            f": no no {f.condition_text}", f": no {f.condition_text}"
        )
    )
    out += [f"{pad}  there is: {n}" for n in f.nearby]
    if isinstance(f.because, Failure):
        _failure_lines(f.because, indent + 2, out)
    elif isinstance(f.because, Proof):
        out.append(f"{pad}  it {verb} because:")
        _proof_lines(f.because, indent + 4, out)


def to_dot(e: Explanation) -> str:
    """Graphviz: one cluster per feature, proofs as trees, failures as red chains."""
    lines = ["digraph explanation {", "  rankdir=LR;", "  node [shape=box, fontsize=10];"]
    counter = itertools.count()

    def quote(text: str) -> str:  # real newlines in `text` become DOT line breaks
        escaped = text.replace("\\", "\\\\").replace('"', '\\"')
        return '"' + escaped.replace("\n", "\\n") + '"'

    def proof(p: Proof) -> str:
        node = f"n{next(counter)}"
        label = p.text + (f"\n{_rule_ref(p.rule)}" if p.rule else f"\n{p.source or ''}")
        style = "" if p.rule else ", style=filled, fillcolor=lightgrey"
        lines.append(f"  {node} [label={quote(label)}{style}];")
        for c in p.children:
            lines.append(f"  {node} -> {proof(c)};")
        return node

    def failure(f: Failure) -> str:
        node = f"n{next(counter)}"
        label = f"{f.text}\nfails at: {f.condition_text}\n{_rule_ref(f.rule)}"
        lines.append(f"  {node} [label={quote(label)}, color=red];")
        if isinstance(f.because, Failure):
            lines.append(f"  {node} -> {failure(f.because)} [color=red];")
        elif isinstance(f.because, Proof):
            lines.append(f"  {node} -> {proof(f.because)};")
        return node

    for i, f in enumerate(e.features):
        lines.append(f"  subgraph cluster_{i} {{ label={quote(f.feature)};")
        for w in f.why:
            root = proof(w.proof)
            lines.append(f"  w{i}_{root} [label={quote('✔ ' + w.topic)}, shape=ellipse];")
            lines.append(f"  w{i}_{root} -> {root};")
        for n in f.why_not:
            root = failure(n.trace)
            lines.append(
                f"  x{i}_{root} [label={quote('✘ ' + n.reason)}, shape=ellipse, color=red];"
            )
            lines.append(f"  x{i}_{root} -> {root};")
        lines.append("  }")
    lines.append("}")
    return "\n".join(lines)
