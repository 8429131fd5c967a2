"""Merge the topics of each feature and synchronise all features into a state stream.

Routing.  A topic of the local platform is read from `/<platform>/<topic>`, `/<topic>` or
`<topic>` in the recording; a remote one from `/<platform>/<topic>` or `<platform>/<topic>`.
A message feeds a feature when every id field of the topic entry holds the required id (ints
and strings compare alike); its field value becomes a sample ⟨available, valid, value⟩.

Merge (thesis 2.2).  A feature's value at time s comes from its sample with the most recent
valid time ≤ s, whichever topic it came on; on equal valid times the local platform wins, then
the order of the stream request.

Synchronise.  States are made at a fixed sample period, or at every sample's valid time ("on
every change"), each once the recording has passed its time plus `delay_before_approximation`.
Approximation "recent" takes the most recent sample up to `max_age` old (older: unknown, null);
"none" takes only a sample at the state's own time (± `sample_period_deviation`).

Constraints (thesis listing 5.2): start/end time, sample period and deviation, max delay,
order and uniqueness of valid times.  Each broken one is reported as a `Violation`; samples
outside start/end are dropped, the others still used where they can be.  A sample arriving after
the states of its valid time were made is reported as late.
"""

from __future__ import annotations

import bisect
import heapq
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Literal

from ..errors import DkError
from ..model import StreamRequest
from . import fields
from .sources import NS, Source


def seconds(ns: int) -> float | int:
    return ns // NS if ns % NS == 0 else ns / NS


@dataclass(frozen=True, slots=True)
class StreamPolicy:
    """Thesis listing 5.2's stream constraints plus the approximation; times in seconds."""

    sample_period: Fraction | None = None  # None: a state on every change
    sample_period_deviation: Fraction = Fraction(0)
    approximation: Literal["recent", "none"] = "recent"
    max_age: Fraction | None = Fraction(5)  # None: a sample never gets too old
    delay_before_approximation: Fraction = Fraction(0)
    start_time: Fraction | None = None
    end_time: Fraction | None = None
    max_delay: Fraction | None = None
    ordered_on_valid_time: bool = False
    unique_valid_time: bool = False


@dataclass(frozen=True, slots=True)
class Violation:
    constraint: str
    time: int  # ns, when it was seen (available time)
    feature: str
    topic: str
    detail: str

    def to_json(self) -> dict[str, Any]:
        return {"violation": self.constraint, "time": seconds(self.time),
                "feature": self.feature, "topic": self.topic, "detail": self.detail}


def _ns(value: Fraction | None) -> int | None:
    if value is None:
        return None
    ns = value * NS
    if ns.denominator != 1:
        raise DkError(f"time {value} s is finer than a nanosecond")
    return int(ns)


class _Route:
    __slots__ = ("q", "get", "prio", "stream")

    def __init__(self, q: int, get: Callable[[Any], Any], prio: int, stream: str) -> None:
        self.q, self.get, self.prio, self.stream = q, get, prio, stream


class _Group:
    """Routes of one recording topic that filter on the same id fields, indexed by id."""

    def __init__(self, id_fields: tuple[str, ...], dicts: bool) -> None:
        self.id_fields = id_fields
        self.getters = tuple(fields.accessor(f, dicts) for f in id_fields)
        self.index: dict[tuple[Any, ...], list[_Route]] = {}

    def add(self, ids: tuple[Any, ...], route: _Route) -> None:
        self.index.setdefault(ids, []).append(route)
        self.index.setdefault(tuple(str(v) for v in ids), []).append(route)

    def routes(self, msg: Any) -> list[_Route]:
        key = tuple(get(msg) for get in self.getters)
        found = self.index.get(key)
        if found is None:
            found = self.index.get(tuple(str(v) for v in key), [])
        return found


class StreamProcessor:
    def __init__(self, request: StreamRequest, policy: StreamPolicy, source: Source,
                 on_state: Callable[[int, dict[str, Any]], None],
                 on_violation: Callable[[Violation], None]) -> None:
        self.policy = policy
        self.on_state, self.on_violation = on_state, on_violation
        self.period, self.deviation = _ns(policy.sample_period), _ns(policy.sample_period_deviation)
        self.max_age, self.delay = _ns(policy.max_age), _ns(policy.delay_before_approximation)
        self.start, self.end = _ns(policy.start_time), _ns(policy.end_time)
        self.max_delay = _ns(policy.max_delay)
        if self.period is not None and self.period <= 0:
            raise DkError("the sample period must be positive")
        self.keys: list[str] = []  # feature keys, as the progressor compares them
        self.hist: list[list[tuple[int, int, Any]]] = []  # per feature: (valid, -prio, value)
        self.groups: dict[str, list[_Group]] = {}
        self.last_valid: dict[str, int] = {}
        self.pending: list[int] = []  # state times to make (on every change)
        self.made: int | None = None  # time of the last state made
        self.next_state: int | None = self.start  # next periodic state time
        self.last_seen: int | None = None
        self.topics: set[str] = set()
        self._route(request, source)

    # ---- set-up: which recording topic feeds which feature, checked before replay -------

    def _route(self, request: StreamRequest, source: Source) -> None:
        types = source.types()
        for q, f in enumerate(request.features):
            self.keys.append("".join(f.feature.key.split()))
            self.hist.append([])
            for prio, m in enumerate(sorted(f.topics, key=lambda t: t.platform != request.local)):
                names = [f"/{m.platform}/{m.topic}", f"{m.platform}/{m.topic}"]
                if m.platform == request.local:
                    names += [f"/{m.topic}", m.topic]
                present = [n for n in names if n in types] if types else names
                if types and present:
                    msgtype = types[present[0]]
                    if msgtype.rsplit("/", 1)[-1] != m.msgtype:
                        raise DkError(f"{source.name}: topic {present[0]} carries {msgtype}, but "
                                      f"its specification says {m.msgtype}")
                    for field in (m.field, *(k for k, _ in m.filter)):
                        why = source.check_field(present[0], field)
                        if why is not None:
                            raise DkError(f"{source.name}: topic {present[0]} ({msgtype}) has no "
                                          f"field {field}: {why}")
                stream = f"{m.platform}/{m.topic}"
                route = _Route(q, fields.accessor(m.field, source.dicts), prio, stream)
                ids = tuple(k for k, _ in m.filter)
                for name in present[:1] if types else present:
                    self.topics.add(name)
                    groups = self.groups.setdefault(name, [])
                    group = next((g for g in groups if g.id_fields == ids), None)
                    if group is None:
                        group = _Group(ids, source.dicts)
                        groups.append(group)
                    group.add(tuple(v for _, v in m.filter), route)

    # ---- replay -------------------------------------------------------------------------

    def feed(self, topic: str, available: int, valid: int, msg: Any) -> None:
        """One message, in recording order."""
        try:
            for group in self.groups[topic]:
                for route in group.routes(msg):
                    self._sample(route, available, valid, route.get(msg))
        except (KeyError, AttributeError, IndexError, TypeError) as exc:
            raise DkError(f"a message on {topic} at {seconds(available)} s lacks a field the "
                          f"request reads ({exc})") from None
        self._emit(available, final=False)

    def finish(self) -> None:
        if self.last_seen is not None:
            self._emit(self.last_seen, final=True)

    def _violation(self, kind: str, available: int, route: _Route, detail: str) -> None:
        self.on_violation(Violation(kind, available, self.keys[route.q], route.stream, detail))

    def _sample(self, route: _Route, available: int, valid: int, value: Any) -> None:
        if hasattr(value, "item"):  # numpy scalars from array fields
            value = value.item()
        if (self.start is not None and valid < self.start) or \
                (self.end is not None and valid > self.end):
            self._violation("start_end_time", available, route,
                            f"valid time {seconds(valid)} s is outside the requested span")
            return
        if self.max_delay is not None and available - valid > self.max_delay:
            self._violation("max_delay", available, route,
                            f"delay {seconds(available - valid)} s exceeds "
                            f"{seconds(self.max_delay)} s")
        last = self.last_valid.get(route.stream)
        if last is not None:
            if valid < last and self.policy.ordered_on_valid_time:
                self._violation("ordered_on_valid_time", available, route,
                                f"valid time {seconds(valid)} s after {seconds(last)} s")
            if valid == last and self.policy.unique_valid_time:
                self._violation("unique_valid_time", available, route,
                                f"second sample at valid time {seconds(valid)} s")
            if self.period is not None and valid > last and \
                    abs(valid - last - self.period) > self.deviation:
                self._violation("sample_period", available, route,
                                f"{seconds(valid - last)} s since the previous sample, expected "
                                f"{seconds(self.period)} ± {seconds(self.deviation)} s")
        if last is None or valid > last:
            self.last_valid[route.stream] = valid
        if self.made is not None and valid <= self.made:
            self._violation("late", available, route,
                            f"sample valid at {seconds(valid)} s arrived at "
                            f"{seconds(available)} s, after the state at {seconds(self.made)} s")
        hist = self.hist[route.q]
        entry = (valid, -route.prio, value)
        if not hist or entry[:2] >= hist[-1][:2]:
            hist.append(entry)
        else:
            bisect.insort(hist, entry, key=lambda e: e[:2])
        if self.period is None:
            if self.made is None or valid > self.made:
                heapq.heappush(self.pending, valid)
        elif self.next_state is None:
            self.next_state = valid

    def _emit(self, now: int, final: bool) -> None:
        self.last_seen = now
        if self.period is None:
            pending = self.pending
            while pending and (final or pending[0] + self.delay < now):
                s = heapq.heappop(pending)
                if self.made is None or s > self.made:
                    self._state(s)
            return
        while self.next_state is not None and (final or self.next_state + self.delay < now):
            if final and self.next_state > max(self.last_valid.values(), default=-1):
                break
            if self.end is not None and self.next_state > self.end:
                break
            self._state(self.next_state)
            self.next_state += self.period

    def _state(self, s: int) -> None:
        values: dict[str, Any] = {}
        for q, hist in enumerate(self.hist):
            i = bisect.bisect_right(hist, (s, 1)) - 1  # the last sample valid at or before s
            value = None
            if i >= 0:
                valid, _, v = hist[i]
                if self.policy.approximation == "none":
                    value = v if s - valid <= self.deviation else None
                elif self.max_age is None or s - valid <= self.max_age:
                    value = v
                if i > 0:
                    del hist[:i]
            values[self.keys[q]] = value
        self.made = s
        self.on_state(s, values)
