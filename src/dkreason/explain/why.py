"""Why a topic was matched: the proof of its relevant_topic row, and its chains in one line
each (the feature, each argument, the topic)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from ..datalog import Row, Value
from ..kb import KnowledgeBase
from ..match import Match, padded
from ..request import topic_match
from .provenance import BRIDGE, Reader
from .replay import Proof, Replayer


@dataclass(frozen=True, slots=True)
class TopicWhy:
    """A matched topic: its id filter, its chains in one line each, and its proof."""

    platform: str
    topic: str
    filter: tuple[tuple[str, Value], ...]
    summary: tuple[str, ...]
    proof: Proof


def topic_why(kb: KnowledgeBase, replay: Replayer, m: Match) -> TopicWhy:
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
    proof = replay.prove(fact)
    assert proof is not None, f"the engine derived {fact} but no clause replays it"
    entry = topic_match(kb, m)
    return TopicWhy(
        m.platform, m.topic, entry.filter if entry else (), _summary(replay.reader, proof), proof
    )


def _summary(reader: Reader, proof: Proof) -> tuple[str, ...]:
    """The proof's chains in one line each: feature, then each argument, then the topic."""
    lines = []
    for node in itertools.islice(proof.find("feature_candidate"), 1):
        _, _, start, end = node.fact
        chain = _chain(
            reader, node, str(start), str(end), ("equivalent_class", "bridge", "subclass_of")
        )
        lines.append(f"feature: {chain}")
    seen = set()
    for node in proof.find("arg_candidate"):
        _, _, start, end = node.fact
        if start == "" or (start, end) in seen:
            continue
        seen.add((start, end))
        lines.append(f"object: {_chain(reader, node, str(start), str(end), ('same_as', 'bridge'))}")
    for node in (*proof.find("accepts"), *proof.find("carries")):
        if node.fact[0] == "accepts":  # accepts(R, T, K, I, C)
            _, _, topic, _, position, obj = node.fact
        else:  # carries(R, G, I, C, T, K): a sort argument found through C's sorts
            _, _, _, position, obj, topic, _ = node.fact
        sort_args = [
            leaf
            for leaf in node.leaves()
            if leaf.fact[0] == "topic_arg" and leaf.fact[5] in ("some", "every")
        ]
        for told in (leaf for leaf in node.leaves() if leaf.fact[0] == "class_type"):
            if sort_args:
                chain = _chain(
                    reader,
                    node,
                    str(told.fact[3]),
                    str(sort_args[0].fact[6]),
                    ("subclass_of", "equivalent_class"),
                )
                entailed = (
                    f" [{told.source}]"
                    if told.source and told.source.startswith("entailed")
                    else ""
                )
                lines.append(
                    f"argument {position} of {topic}: {reader.name(obj)} : {chain}{entailed}"
                )
    carried = (
        f"topic: {leaf.text} [{leaf.source}]"
        for leaf in proof.leaves()
        if leaf.fact[0] == "topic_feature"
    )
    return tuple(lines) + tuple(dict.fromkeys(carried))


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
