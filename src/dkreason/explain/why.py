"""Why a topic was matched: the proof of its relevant_topic row, and its chains in one line
each (the feature, each argument, the topic)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from ..adapt import origin
from ..kb import KnowledgeBase
from ..match import Match, padded
from ..policy.syntax import Row, Value
from ..request import topic_match
from .provenance import BRIDGE, Reader, declared, nanoseconds
from .replay import MAX_DEPTH, Proof, Replayer


@dataclass(frozen=True, slots=True)
class TopicWhy:
    """A matched topic: its id filter, its chains in one line each, and its proof."""

    platform: str
    topic: str
    filter: tuple[tuple[str, Value], ...]
    summary: tuple[str, ...]
    proof: Proof


def topic_why(kb: KnowledgeBase, replay: Replayer, m: Match) -> TopicWhy:
    proof = _proof(replay, m)
    entry = topic_match(kb, m)
    summary = _summary(replay.reader, proof) + _declared(kb, m) + _ranked(replay, m)
    return TopicWhy(m.platform, m.topic, entry.filter if entry else (), summary, proof)


def _declared(kb: KnowledgeBase, m: Match) -> tuple[str, ...]:
    """The topic's declared rate and delay, where its spec says them."""
    spec = kb.platforms[m.platform].specs.get(m.topic)
    quality = declared(spec) if spec is not None else ""
    return (f"declared: {quality} [{spec.span}]",) if spec is not None and quality else ()


def _ranked(replay: Replayer, m: Match) -> tuple[str, ...]:
    """The policy's rank of a topic it ranks, the rule that ranks it and the declared
    properties it ranks by."""
    if not m.rank:
        return ()
    proof = _rank_proof(replay, m)
    where = f" [{proof.rule.span}]" if proof is not None and proof.rule else ""
    text = proof.text if proof is not None else f"rank {m.rank}"
    steps = proof.find("topic_property") if proof else iter(())
    by = dict.fromkeys(p.text for p in steps if p.fact[1:3] == (m.platform, m.topic))
    return (f"{rank_words(replay, m)}: {text}{where}" + "".join(f", by {b}" for b in by),)


def rank_words(replay: Replayer, m: Match) -> str:
    """A topic's rank as a person reads it: the shipped quality rank as `age 350ms` (the
    declared age in nanoseconds), or `no declared age` (ranked after every topic declaring
    one); any other as `rank N`."""
    proof = _rank_proof(replay, m) if m.rank else None
    if proof is None or proof.rule is None or replay.reader.own(proof.rule):
        return f"rank {m.rank}"
    if any(p.fact[1:5] == (m.platform, m.topic, "age", m.rank) for p in proof.steps()):
        return f"age {nanoseconds(m.rank)}"
    return "no declared age" if proof.fact[0] == "topic_rank" else f"rank {m.rank}"


def _rank_proof(replay: Replayer, m: Match) -> Proof | None:
    """The step that ranks a topic (its rank hook's match_result 'rank' row, else its
    topic_rank row), not the answer's routing."""
    answer = replay.prove(
        ("match_result", m.query, "rank", m.platform, m.topic, m.rank, *("",) * 6)
    )
    if answer:
        return next((c for c in answer.children if c.fact[0] != "relevant_topic"), answer)
    return replay.prove(("topic_rank", m.platform, m.topic, m.rank))


# A match no clause replays (a derivation deeper than a replay goes, say) is shown as the
# policy's answer itself: a plainer explanation, not none.
_UNREPLAYED = f"the policy answers it; no proof of at most {MAX_DEPTH} steps replays it"


def _proof(replay: Replayer, m: Match) -> Proof:
    """The proof of the relevant_topic row behind a match, padded as the shipped rules pad;
    else of a relevant_topic or match_result row the match agrees with, however the policy
    pads it; else the answer itself."""
    fact: Row = (
        "relevant_topic",
        m.query,
        m.platform,
        m.topic,
        m.feature_index,
        *padded(m.objects),
        *m.ids,
        *("",) * (3 - len(m.ids)),
    )
    free = (None,) * (3 - len(m.objects))
    found = (m.platform, m.topic, m.feature_index, *m.objects, *free, *m.ids, *free)
    rows = (
        row
        for answer in (
            ("relevant_topic", m.query, *found),
            ("match_result", m.query, "topic", *found),
        )
        for row in replay.rows(answer)
    )
    proof = replay.prove(fact) or next(filter(None, map(replay.prove, rows)), None)
    return proof or Proof(fact, replay.reader.text(fact), source=_UNREPLAYED)


def _worded(reader: Reader, proof: Proof, relation: str) -> Iterator[tuple[Proof, dict[str, Any]]]:
    """The proof's steps through a relation explanations word (WORDED), with their columns:
    none where the policy declares that relation otherwise."""
    for node in proof.find(relation):
        c = reader.columns(node.fact)
        if c:
            yield node, c


def _summary(reader: Reader, proof: Proof) -> tuple[str, ...]:
    """The proof's chains in one line each: feature, then each argument, then the topic."""
    lines = []
    for node, c in itertools.islice(_worded(reader, proof, "feature_candidate"), 1):
        chain = _chain(
            reader,
            node,
            str(c["LocalFeature"]),
            str(c["Feature"]),
            ("equivalent_class", "bridge", "subclass_of"),
        )
        lines.append(f"feature: {chain}")
        owner = reader.kb.platforms.get(str(c["Platform"]))
        if owner is not None and str(c["Feature"]) in owner.ontology.adapted:
            made = origin(owner.ontology, str(c["Feature"]))
            lines.append(f"{reader.name(c['Feature'])} on {owner.name}: {made}")
    seen = set()
    for node, c in _worded(reader, proof, "arg_candidate"):
        start, end = str(c["LocalObject"]), str(c["Object"])
        if start == "" or (start, end) in seen:
            continue
        seen.add((start, end))
        lines.append(f"object: {_chain(reader, node, start, end, ('same_as', 'bridge'))}")
    # a topic argument that accepts an object, or (carries) a sort argument found through the
    # object's sorts
    for node, c in (*_worded(reader, proof, "accepts"), *_worded(reader, proof, "carries")):
        args = [reader.columns(leaf.fact) for leaf in node.leaves() if leaf.fact[0] == "topic_arg"]
        sorts = [arg["Entity"] for arg in args if arg["Kind"] in ("some", "every")]
        for told in (leaf for leaf in node.leaves() if leaf.fact[0] == "class_type"):
            if sorts:
                chain = _chain(
                    reader,
                    node,
                    str(reader.columns(told.fact)["Sort"]),
                    str(sorts[0]),
                    ("subclass_of", "equivalent_class"),
                )
                entailed = (
                    f" [{told.source}]"
                    if told.source and told.source.startswith("entailed")
                    else ""
                )
                lines.append(
                    f"argument {c['Position']} of {c['Topic']}: "
                    f"{reader.name(c['Object'])} : {chain}{entailed}"
                )
    carried = (
        f"topic: {leaf.text} [{leaf.source}]"
        for leaf in proof.leaves()
        if leaf.fact[0] == "topic_feature"
    )
    own = (
        f"rule: {node.text} [{node.rule.span}]"
        for node in proof.steps()
        if node.rule is not None and reader.own(node.rule)
    )
    return tuple(lines) + tuple(dict.fromkeys(carried)) + tuple(dict.fromkeys(own))


def _chain(reader: Reader, node: Proof, start: str, end: str, kinds: tuple[str, ...]) -> str:
    """`A ≡ B (where) ≡ C (where)`: the told links of a proof, in order from start to end."""
    edges = []
    for leaf in node.leaves():
        pred, *a = leaf.fact
        if (
            pred in ("same_rep", "sort_rep")
            and ("same_as" if pred == "same_rep" else "subclass_of") in kinds
        ):
            edges += reader.told_path(leaf.fact)  # a class's representative: the told links
        if pred not in kinds:
            continue
        if pred == "bridge":
            left, right, sym = str(a[1]), str(a[3]), BRIDGE.get(str(a[4]), "?")
            where = f"bridge {a[0]}→{a[2]}, {leaf.source}"
        else:
            left, right = str(a[1]), str(a[2])
            sym = {"equivalent_class": "≡", "same_as": "=", "subclass_of": "⊑"}[str(pred)]
            where = f"{a[0]} axiom, {leaf.source.split(', ')[-1] if leaf.source else ''}"
        edges.append((left, right, sym, where))
    text, current = reader.name(start), start
    while edges:
        step = next((e for e in edges if current in (e[0], e[1])), None)
        if step is None:
            break
        edges.remove(step)
        current = step[1] if step[0] == current else step[0]
        text += f" {step[2]} {reader.name(current)} ({step[3]})"
    if current == start and start == end and not edges:
        text += " (as the formula writes it)" if "bridge" in kinds else ""
    return text
