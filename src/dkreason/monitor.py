"""Close the loop (thesis 2.3.2, 4.4): plan → stream request → Stream Processor → Formula
Progressor → verdicts.  One `Monitor` serves every caller: a recording (`run`), the live
federation (which feeds it samples and re-matches it as platforms come and go), the CLI and
`KnowledgeManager.monitor`.

    for event in km.monitor(["forall c in Car: always (Speed[c] > 60 -> "
                             "eventually[0, 300] Speed[c] <= 60)"], "traffic.mcap"): ...
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Iterator, Sequence
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from .errors import DkError
from .model import FeatureKey, StreamRequest
from .progress import Progressor, Verdict
from .progress.state import USE, feature_uses
from .stream.policy import StreamPolicy
from .stream.processor import StreamProcessor, Violation
from .stream.sources import Source
from .stream.units import NS, seconds

if TYPE_CHECKING:
    from .plan import FormulaPlan, Plan

Event = Verdict | Violation
WORDS: dict[bool | None, str] = {True: "held", False: "violated", None: "unknown"}
"""How a verdict is said, by the CLI, the plot and whatever shows a person one."""


class _Group:
    """The formulas over one set of features, and the state stream they are judged on."""

    def __init__(self, keys: frozenset[FeatureKey]) -> None:
        self.keys = keys
        self.progressor = Progressor(unit=Fraction(1, NS))


class Monitor:
    """A plan (formulas parsed, checked and expanded once) and the match that binds it to
    streams (asked again by `rematch` when the knowledge changes); states in, verdicts out."""

    def __init__(
        self,
        plan: Plan,
        match: Callable[[Plan], StreamRequest],
        policy: StreamPolicy,
        *,
        keep_states: bool = False,
    ) -> None:
        self.plan, self.match, self.policy, self.keep_states = plan, match, policy, keep_states
        self.request = match(plan)
        # A formula is judged on its own state stream: from the first state in which every
        # feature it reads has a value (a recording's warm-up is not "unknown"; with a start
        # time, from the first state on), at the instants its own features are sampled or
        # change.  Formulas over the same features share one progressor.
        self.order = {f.text: n for n, f in enumerate(self.plan.formulas)}
        self.groups: dict[frozenset[FeatureKey], _Group] = {}
        # A state is a group's own when one of its features was sampled or went stale at it
        # (every state with a sample period, and for a group reading no feature): the groups
        # each feature makes due, in the order the groups began.
        self.readers: dict[FeatureKey, list[_Group]] = {}
        self.always: list[_Group] = []
        # the due groups' progressors by the features a state freshly sampled (`_due`)
        self.steps: dict[tuple[FeatureKey, ...] | None, list[Progressor]] = {}
        self.waiting = list(self.plan.formulas)
        if policy.start_time is not None:
            self._begin(self.waiting)
        self.states: list[tuple[int, dict[FeatureKey, Any]]] = []
        self.pending: list[Event] = []
        self.decided = 0
        self.processor: StreamProcessor | None = None

    def start(self, source: Source) -> StreamProcessor:
        """The stream processor over `source`, states going to the progressor; each feature's
        use in the formulas is checked against its fields' types before any message."""
        used = feature_uses((f.text, f.tree) for f in self.plan.formulas)
        self.processor = StreamProcessor(
            self.request,
            self.policy,
            source,
            self._on_state,
            self.pending.append,
            frozenset(k for k, (use, _) in used.items() if use == "string"),
        )
        for k, (use, text) in used.items():
            for topic, field, kind, ros_type in self.processor.kinds.get(k, ()):
                if kind != use:
                    raise DkError(
                        f"{text}: {k} is read from {topic} {field}, "
                        f"{_article(kind, ros_type)}, but the formula uses it as "
                        f"{USE[use]}"
                    )
        return self.processor

    def _begin(self, formulas: list[FormulaPlan]) -> None:
        for f in formulas:
            keys = frozenset(f.keys)
            group = self.groups.get(keys)
            if group is None:
                group = self.groups[keys] = _Group(keys)
                for k in keys:
                    self.readers.setdefault(k, []).append(group)
                if not keys:
                    self.always.append(group)
            group.progressor.add(f.text, f.tree)
            self.waiting.remove(f)
        self.steps.clear()

    def _on_state(
        self, time: int, values: dict[FeatureKey, Any], fresh: tuple[FeatureKey, ...] | None = None
    ) -> None:
        if self.keep_states:
            self.states.append((time, dict(values)))
        if self.waiting:
            self._begin([f for f in self.waiting if all(values[k] is not None for k in f.keys)])
        steps = self.steps.get(fresh)
        if steps is None:
            if len(self.steps) >= 1024:  # many features sampled in many combinations
                self.steps.clear()
            steps = self.steps[fresh] = [g.progressor for g in self._due(fresh)]
        decided: Sequence[Verdict] = ()
        for progressor in steps:  # its stepper changes as formulas are decided
            out = progressor.stepper(time, values)
            if out:
                decided = [*decided, *out]
        if decided:
            self.decided += len(decided)
            origin = self.processor.origin if self.processor is not None else None
            self.pending.extend(
                in_seconds(v, origin) for v in sorted(decided, key=lambda v: self.order[v.formula])
            )

    def _due(self, fresh: tuple[FeatureKey, ...] | None) -> Iterable[_Group]:
        """The groups whose own state this is, in the order they began."""
        if fresh is None:
            return self.groups.values()
        if len(fresh) == 1 and not self.always:
            return self.readers.get(fresh[0], ())
        return [g for g in self.groups.values() if not g.keys or not g.keys.isdisjoint(fresh)]

    @property
    def done(self) -> bool:
        return self.decided == len(self.plan.formulas)

    def events(self) -> list[Event]:
        """What was decided or violated since the last call."""
        out, self.pending[:] = list(self.pending), []
        return out

    def rematch(self, source: Source) -> StreamRequest:
        """The plan's features matched again (the knowledge changed); the streams follow."""
        assert self.processor is not None
        self.request = self.match(self.plan)
        self.processor.reroute(self.request, source)
        return self.request

    def finish(self, end: int | None = None) -> list[Event]:
        """End of stream (at `end`, ns, when known): every formula settled."""
        assert self.processor is not None
        self.processor.finish(end)
        settled = [v for g in self.groups.values() for v in g.progressor.finish()]
        origin = self.processor.origin
        self.pending.extend(
            in_seconds(v, origin) for v in sorted(settled, key=lambda v: self.order[v.formula])
        )
        for f in self.waiting:  # never judged: some feature never had a value
            missing = ", ".join(
                str(g.key)
                for g in f.ground
                if not any(s.get(g.key) is not None for _, s in self.states)
            )
            self.pending.append(
                Verdict(
                    f.text,
                    None,
                    None,
                    True,
                    "no state had a value for every feature it reads"
                    + (f" (never seen: {missing})" if missing and self.keep_states else ""),
                )
            )
        self.waiting = []
        return self.events()

    def run(self, source: Source, progress: Callable[[int], None] | None = None) -> Iterator[Event]:
        """Events as they happen: violations as seen, verdicts as decided, the rest at the end.
        An error in the source comes after every event decided before it."""
        try:
            processor = self.processor or self.start(source)
        except BaseException:
            source.close()
            raise
        pending = self.pending
        try:
            for n in processor.replay(source.messages(processor.wanted), pending):
                if pending:
                    yield from self.events()
                if progress is not None and not n & 4095:
                    progress(n)
        except DkError:  # damage or bad data: first what the messages before it decided
            processor.finish()
            yield from self.events()
            raise
        finally:
            end = source.last_record()
            source.close()
        yield from self.finish(end)


class MonitorRun:
    """One monitoring run over an opened source, as `dkreason monitor` shows it: made, it has
    matched the plan and checked each feature's fields against the recordings (so the stream
    request, the topics no recording holds and the sources' notes can be shown first);
    iterated (once), it yields the events as they happen.  Left unread, close it (or use it
    in a `with` block)."""

    def __init__(self, monitor: Monitor, source: Source) -> None:
        self.monitor, self.source = monitor, source
        try:
            self.processor = monitor.start(source)
        except BaseException:
            source.close()
            raise

    @property
    def request(self) -> StreamRequest:
        return self.monitor.request

    @property
    def absent(self) -> dict[str, tuple[str, ...]]:
        """Spec topics (`platform/topic`) in no recording → the features they would feed."""
        return {t: tuple(dict.fromkeys(fs)) for t, fs in self.processor.absent.items()}

    @property
    def notes(self) -> tuple[str, ...]:
        """What the sources said of themselves: damage read around, the clock chosen."""
        note = getattr(self.source, "note", None)
        return (note,) if note else ()

    @property
    def clock(self) -> str | None:
        """Where valid times come from (`header` stamps or the `record` time), if a choice."""
        clock = getattr(self.source, "clock", None)
        return clock if isinstance(clock, str) else None

    @property
    def start(self) -> Fraction | None:
        """The start of the recording(s), exact seconds: its first record, of any topic, as
        `dkreason info` shows it, where every event's `t` counts from (None until known: a
        JSON lines or pushed source before its first record)."""
        origin = self.processor.origin
        return None if origin is None else Fraction(origin, NS)

    @property
    def states(self) -> list[tuple[int, dict[FeatureKey, Any]]]:
        """The states made (time in ns), when the monitor keeps them (`keep_states`)."""
        return self.monitor.states

    @property
    def messages(self) -> int:
        """Messages read so far on the relevant topics."""
        return self.processor.read

    def count(self) -> int | None:
        """How many messages the sources hold, if they know without reading."""
        return self.source.count(None)

    def events(self, progress: Callable[[int], None] | None = None) -> Iterator[Event]:
        """Events as they happen; `progress` is told how many messages were read."""
        return self.monitor.run(self.source, progress)

    def __iter__(self) -> Iterator[Event]:
        return self.events()

    def close(self) -> None:
        """The sources closed without reading on (iterating to the end closes them too)."""
        self.source.close()

    def __enter__(self) -> MonitorRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _article(kind: str, ros_type: str) -> str:
    if kind in ("message", "array"):
        return "a sub-message" if kind == "message" else "an array"
    return f"a{'n' if ros_type[0] in 'aeiou' else ''} {ros_type}"


def in_seconds(v: Verdict, origin: int | None) -> Verdict:
    """The progressor runs in nanoseconds; people read seconds, on the recording's clock
    (`time`) and from its start (`t`, exact: the difference is taken in nanoseconds)."""
    unknown = tuple(
        dataclasses.replace(u, start=seconds(u.start), end=seconds(u.end)) for u in v.unknown
    )
    return dataclasses.replace(
        v,
        time=None if v.time is None else seconds(v.time),
        t=None if v.time is None or origin is None else seconds(v.time - origin),
        unknown=unknown,
    )
