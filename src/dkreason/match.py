"""Ask the rules (rules/matching.dl) for every ground feature of a formula at once."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from .errors import DkError, MissingIdError, Span
from .kb import KnowledgeBase
from .model import GroundFeature
from .names import local_name
from .policy.syntax import Value


@dataclass(frozen=True, slots=True)
class Match:
    """relevant_topic(Q, Platform, Topic, K, C1…C3, V1…V3) with the padding removed: the
    platform's objects and the id each is selected by ('' where the topic has no id field)."""

    query: int
    platform: str
    topic: str
    feature_index: int
    objects: tuple[str, ...]
    ids: tuple[Value, ...]
    rank: int = 0  # the policy's rank(Q, Platform, Topic, Rank): a request lists smaller first


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


Aside = frozenset[tuple[str, str]]
"""The (platform, topic)s a monitor has set aside, their samples having stopped."""


def given_rows(
    ground: list[GroundFeature], degraded: Aside = frozenset()
) -> dict[str, list[tuple[int | str, ...]]]:
    """What a formula tells the rules while they are asked: its ground features (`wanted`)
    and the sources the monitor has set aside (`degraded`), if any."""
    given: dict[str, list[tuple[int | str, ...]]] = {"wanted": wanted_rows(ground)}
    if degraded:
        given["degraded"] = sorted(degraded)
    return given


def match(
    kb: KnowledgeBase,
    ground: list[GroundFeature],
    max_delay: Fraction | None = None,
    degraded: Aside = frozenset(),
) -> tuple[list[Match], list[Rejected]]:
    """`max_delay`: the monitor's (seconds), which a policy may veto slower topics by;
    `degraded`: the sources the monitor has set aside, which the policy may veto too."""
    given = given_rows(ground, degraded)
    if not given["wanted"]:
        return [], []
    kb.set_max_delay(max_delay)
    engine = kb.engine
    relation = engine.schema["match_result"]
    with engine.given(given):
        rows = engine.query("match_result", *[None] * relation.arity)
    answers, rejected, ranks = [], [], _ranks(engine.rows("topic_rank"))
    for row in rows:
        c = relation.row(row)
        q = int(c["Query"])
        n = len(ground[q].args)
        objects = tuple(str(c[f"Arg{i}"]) for i in range(1, n + 1))
        platform, what = str(c["Platform"]), str(c["What"])
        if c["Answer"] == "topic":
            k = int(c["K"])
            _check_answer(kb, ground[q], platform, what, k)
            ids = tuple(c[f"Filter{i}"] for i in range(1, n + 1))
            answers.append((q, platform, what, k, objects, ids))
        elif c["Answer"] == "rank":  # the rank hook, K the rank
            _rank(ranks, (q, platform, what), c["K"])
        elif c["Answer"] == "rejected":
            rejected.append(Rejected(q, platform, what, objects))
        else:
            raise MissingIdError(
                f"object {local_name(str(c['Arg1']))} on {platform} has no id "
                f"(no id property and no digits ending its name), but topic "
                f"{what} filters on {c['Filter1']}",
                Span(kb.platforms[platform].ontology.file),
            )
    return [
        Match(q, p, t, k, objects, ids, _ranked(ranks, q, p, t))
        for q, p, t, k, objects, ids in answers
    ], rejected


def _ranked(ranks: dict[tuple[Value, ...], int], q: int, platform: str, topic: str) -> int:
    """The smaller of the formula's rank of a topic and the topic's own; 0 without either."""
    mine, own = ranks.get((q, platform, topic)), ranks.get((platform, topic))
    return min(mine, own) if mine is not None and own is not None else mine or own or 0


def _ranks(rows: Sequence[tuple[Value, ...]]) -> dict[tuple[Value, ...], int]:
    """topic_rank(Platform, Topic, Rank) rows: each topic's smallest rank."""
    out: dict[tuple[Value, ...], int] = {}
    for platform, topic, rank in rows:
        _rank(out, (platform, topic), rank)
    return out


def _rank(ranks: dict[tuple[Value, ...], int], key: tuple[Value, ...], rank: Value) -> None:
    """A rank row (rank's or topic_rank's) for `key`: the smallest a topic gets wins."""
    if type(rank) is not int:
        raise DkError(
            f"the policy ranks topic {key[-1]} on {key[-2]} with {rank!r}, not a whole number"
        )
    ranks[key] = min(rank, ranks.get(key, rank))


def _check_answer(kb: KnowledgeBase, g: GroundFeature, platform: str, topic: str, k: int) -> None:
    """A topic answer names a feature a platform's topic carries, with g's arguments: a policy
    of one's own may answer anything, and what follows (the request, explanations) reads it."""
    owner = kb.platforms.get(platform)
    spec = owner.resolved.get(topic) if owner else None
    n = len(g.args)
    if spec is None or not 0 < k <= len(spec.features) or len(spec.features[k - 1].args) != n:
        raise DkError(
            f"the policy answers {g.key} with feature {k} of topic {topic} on {platform}, which "
            f"no topic specification there declares with {n} argument{'s' if n > 1 else ''}"
        )
