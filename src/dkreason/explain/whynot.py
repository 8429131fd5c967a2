"""Why a topic was not chosen: each candidate of the policy (the wanted feature read as a
feature of one platform, its arguments as that platform's objects) with the first condition
of `sound_candidate` or `matched_topic` that fails for it, descending through the rules to the
told facts that are missing."""

from __future__ import annotations

from dataclasses import dataclass

from ..datalog import Row
from ..kb import KnowledgeBase
from .replay import Failure, Replayer


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
    key = replay.reader.ground[q].key
    candidates = replay.rows(("candidate", q, platform, None, None, None, None, None))
    if not candidates:
        failure = replay.refute(("candidate", q, platform, None, None, None, None, None))
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
        arity = len(replay.reader.ground[q].args)
        shown = ", ".join(replay.reader.name(o) for o in objects[:arity])
        mapped = f"{replay.reader.name(g)}[{shown}]"
        sound: Row = ("sound_candidate", q, platform, g, *objects)
        if not replay.holds(sound):
            failure = replay.refute(sound)
            reason = f"{mapped} rejected: {_reason(kb, replay, failure)}"
        else:
            failure = replay.refute(("matched_topic", q, platform, topic, None, *objects))
            reason = f"{_reason(kb, replay, failure)}; {key} maps to {mapped}" + (
                f" on {platform}" if platform != kb.local else ""
            )
        out.append(TopicWhyNot(platform, topic, reason, failure))
    return out


def _reason(kb: KnowledgeBase, replay: Replayer, failure: Failure) -> str:
    """The first failed condition, in the words of the matcher's own relations."""
    cond = failure.condition
    name = replay.reader.name
    if cond is None:
        return failure.condition_text + (
            f" (there is: {failure.nearby[0]})" if failure.nearby else ""
        )
    pred, *a = cond
    if failure.negated:
        if pred == "excluded":
            return f"an incompat bridge rule excludes {name(a[2])} here"
        return f"{failure.condition_text} holds"
    if pred == "fits" and a[3]:
        platform = kb.platforms[str(a[0])]
        return kb.misfit(platform, str(a[1]), int(a[2]), str(a[3]))  # type: ignore[arg-type]
    if pred == "object_candidate":
        return f"{name(a[1])} has no counterpart on {a[0]} (no sameAs or 'same' bridge reaches it)"
    if pred == "feature_candidate":
        return f"{name(a[1])} has no counterpart on {a[0]} (no equivalence reaches it)"
    if pred == "topic_feature" and a[1] is not None:
        carried = [name(r[4]) for r in replay.rows(("topic_feature", a[0], a[1], None, None, None))]
        return f"{a[1]} carries {', '.join(carried) or 'nothing'}, not {name(a[3])}"
    if pred == "accepts" and None not in a[:4]:
        args = replay.rows(("topic_arg", a[0], a[1], a[2], a[3], None, None, None))
        said = ", ".join(f"{r[5]} {name(r[6])}" if r[5] != "object" else name(r[6]) for r in args)
        source = replay.reader.source(args[0]) if args else ""
        return f"argument {a[3]} is {said} ({source}), not {name(a[4])}"
    if isinstance(failure.because, Failure):
        return _reason(kb, replay, failure.because)
    nearby = f" (there is: {failure.nearby[0]})" if failure.nearby else ""
    return f"no {failure.condition_text}{nearby}"
