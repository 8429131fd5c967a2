"""Ask the rules (rules/matching.dl) for every ground feature of a formula at once."""

from __future__ import annotations

from dataclasses import dataclass

from .kb import KnowledgeBase
from .model import GroundFeature


@dataclass(frozen=True, slots=True)
class Match:
    """relevant_topic(Q, Platform, Topic, K, C1, C2, C3) with the padding removed."""

    query: int
    platform: str
    topic: str
    feature_index: int
    objects: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Rejected:
    """rejected_mapping(Q, Platform, G, C1, C2, C3): a remote candidate its ontology rejects."""

    query: int
    platform: str
    feature: str
    objects: tuple[str, ...]


def padded(objects: tuple[str, ...]) -> tuple[str, ...]:
    return objects + ("",) * (3 - len(objects))


def wanted_rows(ground: list[GroundFeature]) -> list[tuple[int | str, ...]]:
    """wanted(Q, F, O1, O2, O3): the facts through which a formula asks the rules."""
    return [(q, g.iri, *padded(g.arg_iris)) for q, g in enumerate(ground)]


def match(kb: KnowledgeBase, ground: list[GroundFeature]) -> tuple[list[Match], list[Rejected]]:
    wanted = wanted_rows(ground)
    if not wanted:
        return [], []
    engine = kb.engine
    engine.assert_rows("wanted", wanted)
    try:
        rows = engine.query("match_result", *[None] * 8)
    finally:
        engine.retract_rows("wanted", wanted)
    matches, rejected = [], []
    for q, kind, platform, what, k, *objects in rows:
        assert isinstance(q, int) and isinstance(k, int)
        trimmed = tuple(str(o) for o in objects[: len(ground[q].args)])
        if kind == "topic":
            matches.append(Match(q, str(platform), str(what), k, trimmed))
        else:
            rejected.append(Rejected(q, str(platform), str(what), trimmed))
    return matches, rejected
