"""An explanation for a formula: per ground feature, why each matched topic was matched, and
for a feature without topics (or a named topic that was not chosen) why not."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from fractions import Fraction

from ..errors import DkError
from ..kb import KnowledgeBase
from ..match import Aside, Match, given_rows
from ..model import FeatureRequest, GroundFeature, TopicMatch, stream_name
from ..parse.formula import feature_key
from .provenance import Reader
from .replay import Replayer
from .why import TopicWhy, rank_words, topic_why
from .whynot import TopicWhyNot, excluded_topics, topic_why_not


@dataclass(frozen=True, slots=True)
class FeatureExplanation:
    """One ground feature: why each of its topics was matched, or why none (or the one named)
    was."""

    feature: str
    why: tuple[TopicWhy, ...]
    why_not: tuple[TopicWhyNot, ...]


@dataclass(frozen=True, slots=True)
class Explanation:
    """What `dkreason explain` prints, as data: a formula and its ground features'."""

    formula: str
    features: tuple[FeatureExplanation, ...]


def explain(
    kb: KnowledgeBase,
    formula: str,
    ground: list[GroundFeature],
    matches: list[Match],
    feature: str | None = None,
    topic: str | None = None,
    max_delay: Fraction | None = None,
    chosen: Sequence[FeatureRequest] | None = None,
) -> Explanation:
    """Why the `matches` of `formula`'s ground features hold (only `feature`'s, only `topic`'s
    if given), and for a feature without them why not, computed on demand: `check_formula`
    does not pay for it.  `chosen`: the --best-source request's features (one per ground
    feature), each topic's line saying whether it is chosen or stands by."""
    selected = list(range(len(ground)))
    if feature is not None:
        wanted_key = feature_key(feature)
        selected = [q for q, g in enumerate(ground) if g.key == wanted_key]
        if not selected:
            raise DkError(
                f"{feature} is not a feature of the formula (its features: "
                f"{', '.join(str(g.key) for g in ground)})"
            )
    if topic is not None and not any(topic in p.specs for p in kb.platforms.values()):
        raise DkError(f"no topic {topic!r} on any platform")
    reader = Reader(kb, ground)
    replay = Replayer(kb, reader)
    kb.set_max_delay(max_delay)
    with kb.engine.given(given_rows(ground)):
        features = []
        for q in selected:
            mine = [m for m in matches if m.query == q and topic in (None, m.topic)]
            why = tuple(topic_why(kb, replay, m) for m in mine)
            if chosen is not None and chosen[q].topics:
                feature_matches = [m for m in matches if m.query == q]
                why = _best(replay, why, mine, chosen[q].topics[0], feature_matches)
            why_not: tuple[TopicWhyNot, ...] = ()
            if not mine:
                platforms = (
                    [p for p, plat in kb.platforms.items() if topic in plat.specs]
                    if topic
                    else [
                        str(reader.columns(r)["Remote"])
                        for r in replay.rows(("context", kb.local, None))
                    ]
                )
                why_not = tuple(
                    w for p in platforms for w in topic_why_not(kb, replay, q, p, topic)
                )
            features.append(FeatureExplanation(str(ground[q].key), why, why_not))
    return Explanation(formula, tuple(features))


def exclusions(
    kb: KnowledgeBase,
    ground: list[GroundFeature],
    empty: Sequence[int],
    max_delay: Fraction | None = None,
    degraded: Aside = frozenset(),
) -> list[str]:
    """Per ground feature left with no topic (`empty`: their indices) whose topics the policy
    excluded, one warning naming them and why, so that a monitor's `never seen` is not read as
    missing data.  Asked after matching and only for those features: a request that finds its
    topics pays nothing."""
    replay = Replayer(kb, Reader(kb, ground))
    kb.set_max_delay(max_delay)
    out = []
    with kb.engine.given(given_rows(ground, degraded)):
        for q in empty:
            lost = excluded_topics(kb, replay, q)
            if lost:
                said = "; ".join(lost)
                out.append(f"{ground[q].key}: every topic of it is excluded by the policy: {said}")
    return out


def _best(
    replay: Replayer,
    why: tuple[TopicWhy, ...],
    mine: list[Match],
    first: TopicMatch,
    feature: list[Match],
) -> tuple[TopicWhy, ...]:
    """Each topic's last line under --best-source: the one chosen, or what ranks another
    after it (a smaller rank first; on the same rank, the local platform, then the order of
    platforms and of the specs).  `feature`: every match of the feature, `mine` those shown."""
    best = (first.platform, first.topic)
    top = min((m for m in feature if (m.platform, m.topic) == best), key=lambda m: m.rank)
    out = []
    for w, m in zip(why, mine, strict=True):
        if (m.platform, m.topic) == best:
            line = "chosen (--best-source): ranked first"
        else:
            order = (
                f"{rank_words(replay, m)} > {rank_words(replay, top)}"
                if m.rank != top.rank
                else "the same rank, after it in the order of platforms and specs"
            )
            after = f"ranked after {stream_name(first.platform, first.topic)} ({order})"
            line = (
                f"standing by (--best-source): {after}; read, and re-routed to if that one "
                "is set aside"
                if first.rate
                else f"not chosen (--best-source): {after}"  # it is never set aside
            )
        out.append(replace(w, summary=(*w.summary, line)))
    return tuple(out)
