"""An explanation as text (the CLI's), JSON (stable, for tools) and Graphviz dot."""

from __future__ import annotations

import itertools
import json
from collections import Counter

from ..errors import DkError
from ..policy.syntax import Rule
from .explanation import Explanation
from .replay import Failure, Proof
from .why import TopicWhy
from .whynot import TopicWhyNot


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


def to_json(e: Explanation, proof: bool = True) -> dict[str, object]:
    """The explanation as JSON (stable, for tools); without `proof`, the answers and their
    one-line reasons only (no proof tree, no why-not trace)."""

    def why(w: TopicWhy) -> dict[str, object]:
        out: dict[str, object] = {
            "platform": w.platform,
            "topic": w.topic,
            "filter": dict(w.filter),
            "summary": list(w.summary),
        }
        if proof:
            out["proof"] = proof_json(w.proof)
        return out

    def why_not(n: TopicWhyNot) -> dict[str, object]:
        out: dict[str, object] = {"platform": n.platform, "topic": n.topic, "reason": n.reason}
        if proof:
            out["trace"] = failure_json(n.trace)
        return out

    return {
        "formula": e.formula,
        "features": [
            {
                "feature": f.feature,
                "why": [why(w) for w in f.why],
                "why_not": [why_not(n) for n in f.why_not],
            }
            for f in e.features
        ],
    }


def render(
    e: Explanation, format: str = "text", *, proof: bool = False, depth: int | None = None
) -> str:
    """The explanation as `dkreason explain --format` prints it: text (the answers and their
    one-line reasons; with `proof`, or to a `depth`, each proof tree and why-not trace too),
    JSON (one line, proofs included) or Graphviz dot."""
    if format == "json":
        return json.dumps(to_json(e), ensure_ascii=False)
    if format == "dot":
        return to_dot(e)
    if format != "text":
        raise DkError(f"no explanation format {format!r} (text, json or dot)")
    return to_text(e, proof or depth is not None, depth)


def to_text(e: Explanation, proof: bool = False, depth: int | None = None) -> str:
    """The answer first: per feature, each topic with its one-line reasons, or why none;
    with `proof`, each proof tree (to `depth`) and why-not trace, a subtree that occurs again
    printed once, numbered, and referred to after that."""
    trees = _Trees([w.proof for f in e.features for w in f.why] if proof else [], depth)
    lines: list[str] = []
    for f in e.features:
        lines.append(f.feature)
        for w in f.why:
            ids = ", ".join(f"{k} = {v}" for k, v in w.filter)
            lines.append(f"  ✔ {w.topic} on {w.platform}" + (f" ({ids})" if ids else ""))
            lines += [f"      {s}" for s in w.summary]
            if proof:
                lines.append("      proof:")
                trees.lines(w.proof, 8, lines)
        for n in f.why_not:
            lines.append(f"  ✘ {n.topic or 'no topic'} on {n.platform}: {n.reason}")
            if proof:
                lines.append("      trace:")
                _failure_lines(n.trace, 8, lines, trees)
        if not f.why and not f.why_not:
            lines.append("  (no topic, and no platform to look on)")
    return "\n".join(lines)


class _Trees:
    """Proof trees as text, to a depth: a derived subtree that occurs more than once among
    `proofs` is printed the first time, numbered, and referred to by its number after that."""

    def __init__(self, proofs: list[Proof], depth: int | None) -> None:
        self.depth = depth
        seen: Counter[Proof] = Counter()
        todo = [(p, 1) for p in proofs]
        while todo:
            p, level = todo.pop()
            if not p.children or (depth is not None and level > depth):
                continue
            seen[p] += 1
            if seen[p] == 1:
                todo += [(c, level + 1) for c in p.children]
        self.repeated = {p for p, n in seen.items() if n > 1}
        self.numbers: dict[Proof, int] = {}

    def lines(self, p: Proof, indent: int, out: list[str], level: int = 1) -> None:
        pad = " " * indent
        if p in self.numbers:
            out.append(f"{pad}{p.text}  (as #{self.numbers[p]} above)")
            return
        where = f"  [{_rule_ref(p.rule)}]" if p.rule else f"  ← {p.source}" if p.source else ""
        if p in self.repeated:
            self.numbers[p] = len(self.numbers) + 1
            where += f"  #{self.numbers[p]}"
        out.append(f"{pad}{p.text}{where}")
        if self.depth is not None and level >= self.depth:
            if p.children:
                out.append(f"{pad}  … {len(p.children)} more below depth {self.depth}")
            return
        for c in p.children:
            self.lines(c, indent + 2, out, level + 1)


def _failure_lines(f: Failure, indent: int, out: list[str], trees: _Trees) -> None:
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
        _failure_lines(f.because, indent + 2, out, trees)
    elif isinstance(f.because, Proof):
        out.append(f"{pad}  it {verb} because:")
        trees.lines(f.because, indent + 4, out)


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
