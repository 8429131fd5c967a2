"""Why a topic was not chosen: each candidate of the policy (the wanted feature read as a
feature of one platform, its arguments as that platform's objects) with the first condition
that fails for it on the steps every policy derives (rules/schema.dl), descending through the
rules to the told facts that are missing."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..kb import KnowledgeBase
from ..model import stream_name
from ..policy.syntax import Row
from .provenance import Pattern
from .replay import Failure, Proof, Replayer


@dataclass(frozen=True, slots=True)
class TopicWhyNot:
    """A topic (or, with none named, any topic) not chosen on a platform: the reason in one
    line, and the trace of failed goals behind it."""

    platform: str
    topic: str | None
    reason: str
    trace: Failure


def topic_why_not(
    kb: KnowledgeBase, replay: Replayer, q: int, platform: str, topic: str | None
) -> list[TopicWhyNot]:
    """Per candidate of wanted feature `q` on `platform`, the first step that does not hold for
    it (sound, a matched topic, a relevant topic, the policy's answer) and the condition that
    fails there.  A policy may derive a step without the one before: each step is asked."""
    reader = replay.reader
    key = reader.ground[q].key
    wanted: Pattern = ("candidate", q, platform, None, None, None, None, None)
    candidates = replay.rows(wanted)
    if not candidates:
        failure = replay.refute(wanted)
        return [
            TopicWhyNot(
                platform,
                topic,
                f"{key} has no candidate on {platform}: {_reason(kb, replay, failure)}",
                failure,
            )
        ]
    out = []
    for _, _, _, _, g, *objects in candidates:
        arity = len(reader.ground[q].args)
        mapped = f"{reader.name(g)}[{', '.join(reader.name(o) for o in objects[:arity])}]"
        sound: Row = ("sound_candidate", q, platform, g, *objects)
        if not replay.holds(sound):
            failure = replay.refute(sound)
            reason = f"{mapped} rejected: {_reason(kb, replay, failure)}"
        else:
            failure = _unmatched(replay, sound, topic)
            reason = f"{_reason(kb, replay, failure)}; {key} maps to {mapped}" + (
                f" on {platform}" if platform != kb.local else ""
            )
        out.append(TopicWhyNot(platform, topic, reason, failure))
    return out


def excluded_topics(kb: KnowledgeBase, replay: Replayer, q: int) -> list[str]:
    """The topics carrying wanted feature `q`'s candidates that the policy excluded (an
    excluded_topic, a veto, a source set aside), each as `platform:topic (why)`: what a feature
    left with no topic lost to the policy, not to missing data."""
    reader = replay.reader
    out: dict[str, None] = {}
    for context in replay.rows(("context", kb.local, None)):
        platform = str(reader.columns(context)["Remote"])
        for candidate in replay.rows(("candidate", q, platform, None, None, None, None, None)):
            carrying = replay.rows(("topic_feature", platform, None, None, candidate[4], None))
            for topic in dict.fromkeys(str(row[2]) for row in carrying):
                for w in topic_why_not(kb, replay, q, platform, topic):
                    if w.trace.negated:
                        why = _reason(kb, replay, w.trace)
                        out[f"{stream_name(platform, topic)} ({why})"] = None
    return list(out)


def _unmatched(replay: Replayer, sound: Row, topic: str | None) -> Failure:
    """The first step after a sound candidate that does not hold for it: a topic matched to
    it (one whose K-th feature is the candidate's, as the schema says matched_topic's K is),
    that topic relevant, the policy's answer naming it."""
    _, q, platform, g, *objects = sound
    matched: Pattern = ("matched_topic", q, platform, topic, None, *objects)
    mine = [
        (t, k)
        for _, _, _, t, k, *_ in replay.rows(matched)
        if replay.rows(("topic_feature", platform, t, k, g, None))
    ]
    excluded: Row = ("excluded_topic", platform, topic or "")
    if not mine and topic is not None and replay.holds(excluded):  # whatever the formula
        text = replay.reader.text(excluded)
        proof = replay.prove(excluded)
        return Failure(matched, replay.reader.text(matched), None, excluded, text, True, (), proof)
    if not mine:
        return replay.refute(matched, assume=sound)
    later: list[Pattern] = [
        ("relevant_topic", q, platform, t, k, *objects, None, None, None) for t, k in mine
    ]
    if any(replay.rows(s) for s in later):
        later = [
            ("match_result", q, "topic", platform, t, k, *objects, None, None, None)
            for t, k in mine
        ]
    return replay.refute(next((s for s in later if not replay.rows(s)), later[0]))


def _reason(kb: KnowledgeBase, replay: Replayer, failure: Failure) -> str:
    """The first failed condition, in the words of the relations explanations know (the
    schema's, and WORDED as the policy declares them), else as the condition reads."""
    cond = failure.condition
    reader = replay.reader
    name = reader.name
    if cond is None:
        return failure.condition_text + (
            f" (there is: {failure.nearby[0]})" if failure.nearby else ""
        )
    pred, c = cond[0], reader.columns(cond)
    if failure.negated:
        if pred == "excluded" and c:
            return f"an incompat bridge rule excludes {name(c['Feature'])} here"
        if pred == "degraded" and c:
            return f"the monitor set {c['Topic']} aside on {c['Platform']}: its samples stopped"
        because = failure.because
        rule = because.rule if isinstance(because, Proof) else None
        rests = _told(because) if isinstance(because, Proof) else ""
        return f"{failure.condition_text} holds" + (f" [{rule.span}]" if rule else "") + rests
    misfit = _misfit(kb, c) if pred == "fits" and c["Entity"] else None
    if misfit:
        return misfit
    if pred == "object_candidate" and c:
        return (
            f"{name(c['LocalClass'])} has no counterpart on {c['Platform']} "
            "(no sameAs or 'same' bridge reaches it)"
        )
    if pred == "feature_candidate" and c:
        return (
            f"{name(c['LocalFeature'])} has no counterpart on {c['Platform']} "
            "(no equivalence reaches it)"
        )
    if pred == "topic_feature" and c["Topic"] is not None:
        told = replay.rows(("topic_feature", c["Platform"], c["Topic"], None, None, None))
        carried = ", ".join(name(reader.columns(r)["Feature"]) for r in told) or "nothing"
        return f"{c['Topic']} carries {carried}, not {name(c['Feature'])}"
    if pred == "accepts" and c and None not in cond[1:5]:
        args = replay.rows(
            ("topic_arg", c["Platform"], c["Topic"], c["K"], c["Position"], None, None, None)
        )
        said = ", ".join(
            name(a["Entity"]) if a["Kind"] == "object" else f"{a['Kind']} {name(a['Entity'])}"
            for a in map(reader.columns, args)
        )
        source = reader.source(args[0]) if args else ""
        return f"argument {c['Position']} is {said} ({source}), not {name(c['Object'])}"
    if isinstance(failure.because, Failure):
        return _reason(kb, replay, failure.because)
    nearby = f" (there is: {failure.nearby[0]})" if failure.nearby else ""
    return f"no {failure.condition_text}{nearby}"


# Told facts a veto's proof rests on that say why in words (the declared quality).
_WHY_VETOED = ("topic_property", "max_delay")


def _told(proof: Proof) -> str:
    """What a proof of a negated condition (a veto) rests on, of the facts that say why."""
    said = dict.fromkeys(leaf.text for leaf in proof.leaves() if leaf.fact[0] in _WHY_VETOED)
    return f": {', '.join(said)}" if said else ""


def _misfit(kb: KnowledgeBase, fits: dict[str, Any]) -> str | None:
    """Why Entity does not fit argument Position of Feature on Platform, where these name a
    platform, one of its features and an argument of it."""
    platform = kb.platforms.get(str(fits["Platform"]))
    if platform is None:
        return None
    feature = platform.ontology.features.get(str(fits["Feature"]))
    position = fits["Position"]
    if not (feature and isinstance(position, int) and 0 < position <= len(feature.arg_sorts)):
        return None
    return kb.misfit(platform, str(fits["Feature"]), position, str(fits["Entity"]))
