"""Merge the topics of each feature and synchronise all features into a state stream.

Routing.  A topic of the local platform is read from `/<platform>/<topic>`, `/<topic>` or
`<topic>` in the recording; a remote one from `/<platform>/<topic>` or `<platform>/<topic>`.
A message feeds a feature when every id field of the topic entry holds the required id (ints
and strings compare alike); its field value becomes a sample ⟨available, valid, value⟩.

Merge (thesis 2.2).  A feature's value at time s comes from its sample with the most recent
valid time ≤ s, whichever topic it came on; on equal valid times the local platform wins, then
the order of the stream request, then the later arrival.  A topic standing by (--best-source)
feeds nothing; each of its routes keeps its newest message, which feeds the feature at once
when the topic takes the chosen one's place (`reroute`), so a switch loses no value it sent.

Synchronise.  States are made at a fixed sample period, or at every sample's valid time ("on
every change", plus the instant a sample grows older than `max_age`, so a value that went
stale between samples shows as unknown), each once the recording has passed its time plus
`delay_before_approximation`.
Approximation "recent" takes the most recent sample up to `max_age` old (older: unknown, null);
"none" takes only a sample at the state's own time (± `sample_period_deviation`).

Window.  A start and end time bound what is judged: messages valid outside them are skipped
(silently: they are not the data asked about), and once the recording passes the end (plus the
delay) nothing more is read: the end of the window is the end of the data.  Bounds counted from
the start of the recording (`+SECONDS`) are placed on the time axis at the first message.

Time axis.  `t` counts from the start of the recording as `dkreason info` shows it, its first
record of any topic (`Source.first_record`; live, the first message put), whatever features
are read.

Constraints (thesis listing 5.2): sample period and deviation, max delay, order and uniqueness
of valid times.  Each broken one is reported as a `Violation`; the samples are still used where
they can be.  A sample arriving after the states of its valid time were made is reported as
late.  A topic whose spec declares its rate or delay is held to them (quality.py).
"""

from __future__ import annotations

import bisect
import heapq
import math
import numbers
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sized
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from itertools import chain
from operator import itemgetter
from typing import Any

from ..errors import DkError
from ..inputs.numbers import datum
from ..model import FeatureKey, StreamRequest, stream_name
from .policy import StreamPolicy
from .quality import Found, Move, QualityWatch
from .sources import Message, Source
from .terms import term_key, term_value
from .units import NS, seconds

_INF = float("inf")
MAX_STATES = 10**7  # states a sample period may make over a stream (a few µs each: a minute)
_NO_EXPIRY: tuple[list[FeatureKey], list[int]] = ([], [])  # read, never changed
_NO_QS: list[int] = []
_VALID_RANK = itemgetter(0, 1)  # a history entry's order: (valid, rank), never its value
_VALID = itemgetter(0)
_SECOND = Fraction(1, NS)  # seconds per stream unit


@dataclass(frozen=True, slots=True)
class Violation:
    constraint: str
    time: float | int  # s, when it was seen (available time), like a Verdict's
    feature: FeatureKey
    topic: str
    detail: str
    t: float | int | None = None  # s from the start of the recording, exact

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"violation": self.constraint, "time": self.time}
        if self.t is not None:
            out["t"] = self.t
        return out | {"feature": str(self.feature), "topic": self.topic, "detail": self.detail}


def _ns(value: Fraction | None) -> int | None:
    return None if value is None else _ns_given(value)


def _ns_given(value: Fraction) -> int:
    ns = value * NS
    if ns.denominator != 1:
        raise DkError(f"time {value} s is finer than a nanosecond")
    return int(ns)


class _Route:
    """One topic entry of one feature: a source stream, with its latest valid time (kept when
    a constraint needs it); standing by (--best-source), the newest message it would have fed
    the feature (`held`), which it feeds at once if it takes the chosen topic's place."""

    __slots__ = ("q", "get", "rank", "stream", "last", "text", "held")

    def __init__(
        self, q: int, get: Callable[[Any], Any], prio: int, stream: str, text: bool
    ) -> None:
        self.q, self.get, self.stream, self.text = q, get, stream, text
        self.rank = -prio  # a feature's history is ordered by (valid, rank)
        self.last: int | None = None
        self.held: Message | None = None


class _Group:
    """Routes of one recording topic that filter on the same id fields, indexed by id."""

    def __init__(self, id_fields: tuple[str, ...], positions: tuple[int, ...]) -> None:
        self.id_fields = id_fields
        # a message's ids in one C call: the value itself for one id field, else a tuple
        self.key: Callable[[Any], Any] = itemgetter(*positions) if positions else (lambda _: ())
        self.index: dict[Any, list[_Route]] = {}

    def all(self) -> Iterator[_Route]:
        return iter(dict.fromkeys(r for routes in self.index.values() for r in routes))

    def add(self, ids: tuple[Any, ...], route: _Route) -> None:
        for key in dict.fromkeys((ids, tuple(str(v) for v in ids))):  # once if alike
            self.index.setdefault(key[0] if len(key) == 1 else key, []).append(route)

    def routes(self, msg: Any) -> list[_Route]:
        key = self.key(msg)
        try:
            found = self.index.get(key)
        except TypeError:  # an unhashable id (a list or a map): no object has it
            return []
        if found is None:  # ids compare alike as ints and strings
            text = tuple(str(v) for v in key) if len(self.id_fields) > 1 else str(key)
            found = self.index.get(text, [])
        return found


def _prune(hist: list[Any], i: int) -> None:
    """Drop the samples of a history never read again once sample i is the newest valid: all
    before it but the newest of an earlier time (what `prev` reads), however many share i's
    time (a flood stamped alike: found by bisection, not by walking back)."""
    j = bisect.bisect_left(hist, (hist[i][0],)) - 1
    del hist[j + 1 : i]
    if j > 0:
        del hist[:j]


class StreamProcessor:
    def __init__(
        self,
        request: StreamRequest,
        policy: StreamPolicy,
        source: Source,
        on_state: Callable[[int, dict[FeatureKey, Any], tuple[FeatureKey, ...] | None], None],
        on_violation: Callable[[Violation], None],
        texts: frozenset[FeatureKey] = frozenset(),
        terms: Iterable[tuple[str, FeatureKey]] = (),
        moved: Callable[[Move], None] | None = None,
        limits: Iterable[tuple[FeatureKey, Fraction]] = (),
    ) -> None:
        """`on_state(time, values, fresh)` gets each state: `values` is read during the call
        only (on every change it is the processor's own dict, changed in place for the next
        state: a state costs what changed).  `texts`: the features the formulas compare with
        strings (their values are kept as strings; any other feature's value must be a number
        or boolean).  `terms`: the terms over samples (`("rate", Yaw[r1])`) the formulas read,
        each a value of the states (stream.terms).  `moved`: told when a topic declaring a
        rate is set aside or taken back (quality.py; the caller matches again).  `limits`: the
        ages the formulas' truth turns at (`fresh(X, d)`, `age(X) <= d`), as (X, d): on every
        change, a state is made at the instant X's newest sample grows older than d
        (`deadlines`)."""
        self.texts = texts
        self.policy = policy
        self.source = source
        self.on_state, self.on_violation = on_state, on_violation
        self.period = _ns(policy.sample_period)
        self.deviation = _ns_given(policy.sample_period_deviation)
        self.max_age = _ns(policy.max_age)
        # a sample's value grows stale (and a state is due when it does)
        self.expiring = self.max_age is not None and policy.approximation == "recent"
        self.stale_after = 0 if self.max_age is None else self.max_age + 1  # past its valid time
        self.delay = _ns_given(policy.delay_before_approximation)
        # the window: placed on the time axis at the first message (`_place`)
        self.start, self.end = _ns(policy.start_time), _ns(policy.end_time)
        self.windowed = self.start is not None or self.end is not None
        self.placed = False
        self.first_taken: int | None = None  # the first message's available time (live)
        self.max_delay = _ns(policy.max_delay)
        if self.period is not None and self.period <= 0:
            raise DkError("the sample period must be positive")
        self.recorded_end = source.last_record()  # where a recording ends (ns), if known
        self.sized = False  # the periodic states to the stream's known end were counted
        self.keys: list[FeatureKey] = []  # the states' keys
        self.position: dict[FeatureKey, int] = {}  # each key's place in them
        self.current: dict[FeatureKey, Any] = {}  # the last state's values (on every change)
        self.hist: list[list[tuple[int, int, Any]]] = []  # per feature: (valid, -prio, value)
        self.groups: dict[str, list[_Group]] = {}
        # --best-source: the routes of the topics standing by, which only hold each route's
        # newest message (a topic that feeds nothing has no routes in `groups`)
        self.standing: dict[str, list[_Group]] = {}
        self.absent: dict[str, list[str]] = {}  # spec topic in no recording → its features
        # feature → (recording topic, field, kind, ROS type) of each topic that feeds it
        self.kinds: dict[FeatureKey, list[tuple[str, str, str, str]]] = {}
        # on every change: state times to make, in order (samples in valid-time order), as a
        # heap (the others), and when each feature's latest sample grows stale (rescheduled
        # lazily: `due` holds the newest time, the heap at most one entry per feature)
        self.times: deque[int] = deque()
        self.at: deque[list[int]] = deque()  # beside times: the features sampled at each
        self.out_of_order: list[tuple[int, int]] = []  # (time, feature sampled at it)
        self.expiries: list[tuple[int, int, bool]] = []  # (time, feature, fixed?)
        self.due: list[int] = []
        self.queued: list[bool] = []
        # `limits`: for each feature, the times after its newest sample at which an age
        # bound turns (d, and 1 ns); and when (time, feature, that offset) as a heap, one
        # entry per feature and offset, rescheduled lazily (`_passed`)
        self.limits: dict[int, tuple[int, ...]] = {}
        self.deadlines: list[tuple[int, int, int]] = []
        self.timed: set[tuple[int, int]] = set()  # the (feature, offset)s in the heap
        self.max_valid = -1
        self.quiet_until: float = float("inf")  # no state is due while times stay at or below
        self.checks = policy.ordered_on_valid_time or policy.unique_valid_time
        self.strict = self.max_delay is not None or self.checks or self.period is not None
        self.recent = policy.approximation == "recent"
        # on every change with the recent approximation, a state reads only what changed
        self.incremental = self.period is None and self.recent
        self.redo: set[int] = set()  # features a late sample reached since the last state
        self.made: float = -_INF  # time of the last state made (ns)
        self.next_state: int | None = None if policy.span_from_start else self.start
        # on every change, with a start time: the state made at it, every feature's value
        # there (unknown unless sampled then), so formulas are judged from that instant
        self.opening: int | None = None
        self.last_seen: int | None = None
        self.read = 0  # messages replayed on the relevant topics
        self.wanted: dict[str, list[str]] = {}  # recording topic → fields its messages give
        # the topics that declare their rate or delay
        self.quality = QualityWatch(policy.set_aside_after, moved)
        for f in request.features:
            self._feature(f.feature.key)
        self.terms: dict[FeatureKey, tuple[str, int]] = {}
        self.want(terms, limits)
        self.quiet_until = self._next_due()  # with a period and a start: its first state
        self._route(request, source)
        origin = source.first_record()
        if origin is not None:  # a recording: topics that send nothing are silent from it
            self.quality.begin(origin)

    def _feature(self, key: FeatureKey) -> None:
        self.position[key] = len(self.keys)
        self.keys.append(key)
        self.current[key] = None
        self.hist.append([])
        self.due.append(-1)
        self.queued.append(False)

    def want(
        self,
        terms: Iterable[tuple[str, FeatureKey]],
        limits: Iterable[tuple[FeatureKey, Fraction]] = (),
    ) -> None:
        """The terms over samples the states carry from now on, and the ages (`limits`)
        whose deadlines make states."""
        self.terms = {term_key(op, k): (op, self.position[k]) for op, k in terms}
        offsets: dict[int, set[int]] = {}
        for k, d in limits:  # older than d: d and 1 ns past the sample, in whole ns
            offsets.setdefault(self.position[k], set()).add(math.floor(d * NS) + 1)
        self.limits = {q: tuple(sorted(o)) for q, o in offsets.items()}

    def _terms(self, s: int, values: dict[FeatureKey, Any]) -> None:
        """Each term at s, from its feature's newest sample valid by then and the one before
        it (the newest of an earlier valid time)."""
        for k, (op, q) in self.terms.items():
            hist = self.hist[q]
            i = (
                len(hist) - 1
                if hist and hist[-1][0] <= s
                else bisect.bisect_right(hist, (s, 1)) - 1
            )
            last = prev = None
            if i >= 0:
                valid = hist[i][0]
                last = (valid, hist[i][2])
                j = i - 1
                while j >= 0 and hist[j][0] == valid:
                    j -= 1
                prev = (hist[j][0], hist[j][2]) if j >= 0 else None
            values[k] = term_value(op, s, last, prev, _SECOND)

    def _open(self, start: int) -> None:
        """A state is due at the start time (on every change; periodic states start there)."""
        if self.period is None:
            self.opening = start
            self.times.appendleft(start)
            self.at.appendleft([])

    @property
    def origin(self) -> int | None:
        """Where the time axis starts (ns): the recording's first record, of any topic (live:
        the first message put); None before it is known."""
        known = self.source.first_record()
        return self.first_taken if known is None else known

    def reroute(self, request: StreamRequest, source: Source) -> None:
        """New topics for the features (a live federation changed, a source was set aside),
        and new features (objects joined a sort a formula ranges over): what each feature has
        seen so far stays.  Changed in place, so a replay under way reads on (a topic keeps
        its fields' places); a topic set aside is still read, feeding nothing, so its return
        is seen."""
        keys = [f.feature.key for f in request.features]
        if set(self.keys) - set(keys):
            raise DkError("a new route must keep the features of the stream request")
        for key in keys:
            if key not in self.position:
                self._feature(key)
        before = {topic: fields_ for topic, fields_ in self.wanted.items()}
        held = {
            (name, r.q, r.stream): r.held
            for name, groups in self.standing.items()
            for g in groups
            for r in g.all()
            if r.held is not None
        }
        self.groups.clear()
        self.standing.clear()
        self.wanted.clear()
        self.source = source
        promoted = self._route(request, source, before, held)
        for topic in self.quality.aside():
            if topic in before:
                self.wanted.setdefault(topic, before[topic])
                self.groups.setdefault(topic, [])
        for route, message in promoted:
            self._promote(route, message)

    def _promote(self, route: _Route, message: Message) -> None:
        """A topic that stood by feeds its feature now (the chosen one was set aside): the
        newest message it held gives the feature its value at once, at its valid time unless
        a state was made since, else now (the switch), so no value it sent is lost to it."""
        topic, available, valid, values = message
        if valid <= self.made:
            assert self.last_seen is not None  # a state was made: time has been seen
            valid = self.last_seen
        group = _Group((), ())
        group.add((), route)
        fed: Iterable[Message] = ((topic, available, valid, values),)
        for _ in self._take(self._windowed(fed) if self.windowed else fed, None, {topic: [group]}):
            pass

    # ---- set-up: which recording topic feeds which feature, checked before replay -------

    def _route(
        self,
        request: StreamRequest,
        source: Source,
        before: dict[str, list[str]] | None = None,
        held: dict[tuple[str, int, str], Message] | None = None,
    ) -> list[tuple[_Route, Message]]:
        """`before`: each topic's fields as read so far, kept in their places; `held`: the
        newest message of each route that stood by, by (topic, feature, stream).  Returns
        the routes that stood by and feed now, with their held messages."""
        from .binding import message_type_fits, recording_names

        before, held = before or {}, held or {}
        promoted = []

        types = source.types()
        namespaces = dict(request.namespaces)
        for f in request.features:
            q = self.position[f.feature.key]
            feeding = sorted(f.topics, key=lambda t: t.platform != request.local)
            for prio, m in enumerate((*feeding, *f.standby)):
                names = recording_names(
                    m, request.local, namespaces.get(m.platform), request.shared_names
                )
                present = [n for n in names if n in types] if types else names
                standby = prio >= len(feeding)
                if types and not present and not standby:
                    self.absent.setdefault(stream_name(m.platform, m.topic), []).append(
                        str(f.feature.key)
                    )
                if types and present:
                    msgtype = types[present[0]]
                    if not message_type_fits(msgtype, m.msgtype):
                        raise DkError(
                            f"{source.name}: topic {present[0]} carries {msgtype}, but "
                            f"its specification says {m.msgtype}"
                        )
                    for field in (m.field, *(k for k, _ in m.filter)):
                        why = source.check_field(present[0], field)
                        if why is not None:
                            raise DkError(
                                f"{source.name}: topic {present[0]} ({msgtype}) has no "
                                f"field {field}: {why}"
                            )
                    kind = source.field_kind(present[0], m.field)
                    if kind is not None:
                        self.kinds.setdefault(f.feature.key, []).append(
                            (present[0], m.field, *kind)
                        )
                stream = stream_name(m.platform, m.topic)
                ids = tuple(k for k, _ in m.filter)
                names = present[:1] if types else present
                self.quality.declare(
                    names, f.feature.key, m.platform, m.topic, m.rate, m.delay, self.last_seen
                )
                for name in names:
                    if name in before and name not in self.wanted:
                        self.wanted[name] = list(before[name])
                    route = _Route(
                        q,
                        itemgetter(self._position(name, m.field)),
                        prio,
                        stream,
                        f.feature.key in self.texts,
                    )
                    kept = held.get((name, q, stream))
                    if standby:  # read and watched, feeding nothing: its newest message held
                        route.held = kept
                        self.groups.setdefault(name, [])
                    elif kept is not None:
                        promoted.append((route, kept))
                    groups = (self.standing if standby else self.groups).setdefault(name, [])
                    group = next((g for g in groups if g.id_fields == ids), None)
                    if group is None:
                        group = _Group(ids, tuple(self._position(name, f) for f in ids))
                        groups.append(group)
                    group.add(tuple(v for _, v in m.filter), route)
        return promoted

    def _position(self, topic: str, field: str) -> int:
        """Where `field` stands in the values a message of `topic` gives."""
        fields_ = self.wanted.setdefault(topic, [])
        if field not in fields_:
            fields_.append(field)
        return fields_.index(field)

    # ---- replay -------------------------------------------------------------------------

    def replay(self, messages: Iterable[Message], watch: Sized = ()) -> Iterator[int]:
        """Messages in recording order (each with the values `wanted` names): their samples,
        and the states they make due.  Yields the count of messages so far after one that
        left `watch` (the caller's pending events) not empty, and after every 4096th."""
        if self.quality.start is None and self.quality.watched:
            messages = self._begun(messages)
        return self._take(self._windowed(messages) if self.windowed else messages, watch)

    def _begun(self, messages: Iterable[Message]) -> Iterator[Message]:
        """A source whose start is known only once read: the watched topics are silent
        from its first message."""
        it = iter(messages)
        head = next(it, None)
        if head is None:
            return it
        origin = self.origin
        self.quality.begin(head[1] if origin is None else origin)
        return chain((head,), it)

    def put(self, topic: str, available: int, valid: int, values: tuple[Any, ...]) -> None:
        """A message, without making states: a live source says when time has passed."""
        if self.first_taken is None:
            self.first_taken = available
            self.quality.begin(available)  # unless the stream clock started before
        message: Iterable[Message] = ((topic, available, valid, values),)
        for _ in self._take(self._windowed(message) if self.windowed else message, None):
            pass

    def early(self, topic: str, available: int, valid: int, values: tuple[Any, ...]) -> None:
        """A message a live source refuses, valid too far past its stream clock
        (`available`): an `early` violation of each feature it would feed, and nothing
        taken, so the end of the data, up to which every other feature is judged, stays."""
        for group in self.groups.get(topic, ()):
            for route in group.routes(values):
                self._violation(
                    "early",
                    available,
                    route,
                    f"sample valid at {seconds(valid)} s arrived at {seconds(available)} s "
                    f"on the stream clock, {seconds(valid - available)} s ahead of it: not taken",
                )

    def _windowed(self, messages: Iterable[Message]) -> Iterator[Message]:
        """The messages valid within the window, until the recording passes its end by the
        delay (no state in the window is left to make then).  The first message is read now,
        to place the window before any is taken."""
        it = iter(messages)
        head = next(it, None)
        if head is None:
            return it
        if not self.placed:
            self._place(head[1])
        return self._within(chain((head,), it))

    def _within(self, messages: Iterator[Message]) -> Iterator[Message]:
        start = -_INF if self.start is None else self.start
        end = _INF if self.end is None else self.end
        stop, taken = end + self.delay, False
        for message in messages:
            if message[1] > stop:
                if not taken and self.read == 0:
                    self._nothing_judged()
                return
            if start <= message[2] <= end:
                taken = True
                yield message

    def _nothing_judged(self) -> None:
        """The recording passed the end of the window before any message fell in it: a
        window that ends before the recording starts is an error, not a run that judges
        nothing (on an epoch clock `--end 10` is in 1970)."""
        origin = self.origin
        if self.end is not None and origin is not None and self.end < origin:
            end = seconds(self.end)
            raise DkError(
                f"the end time {end} s is before the recording starts (at {seconds(origin)} s): "
                f"nothing would be judged; +{end} is {end} s after its start"
            )

    def _place(self, available: int) -> None:
        """The window on the time axis, at the first message (`available`; by then every
        recording has been read from): bounds counted from the start of the recording move
        there."""
        self.placed = True
        origin = self.origin
        if origin is None:
            origin = self.first_taken = available
        if self.policy.span_from_start:
            self.start = None if self.start is None else origin + self.start
            self.end = None if self.end is None else origin + self.end
            if self.period is not None:
                self.next_state = self.start
        if self.start is not None:
            self._open(self.start)
        self.quiet_until = self._next_due()

    def _take(
        self,
        messages: Iterable[Message],
        watch: Sized | None,
        feeding: dict[str, list[_Group]] | None = None,
    ) -> Iterator[int]:
        """The replay's hot path, written out in one loop with the processor's state in
        locals between states (`watch` None: make no state).  Each value a message gives a
        feature is a sample; with no constraint set, in valid-time order, a sample costs its
        history entry, its state time and its expiry.  `feeding`: fed instead of the topics'
        own (a held message, promoted: neither watched nor held again)."""
        quality = self.quality
        own = feeding is None
        groups = self.groups if feeding is None else feeding
        declared = quality.topics if own else {}
        watching = quality.watched if own else {}
        standing = self.standing if own else {}
        hists, times, at, due, queued = (
            self.hist,
            self.times,
            self.at,
            self.due,
            self.queued,
        )
        stale_after, delay, expiring, strict = (
            self.stale_after,
            self.delay,
            self.expiring,
            self.strict,
        )
        periodic = self.period is not None
        limits = self.limits
        max_valid, quiet = self.max_valid, self.quiet_until
        made = self.made
        n, seen = 0, None
        try:
            for topic, available, valid, values in messages:
                if declared and topic in declared:
                    self._report(quality.sample(topic, available, valid))
                if standing and topic in standing:
                    self._hold(standing[topic], (topic, available, valid, values))
                for group in groups[topic]:
                    try:  # `_Group.routes`, its common case inline: a hashable id, found
                        routes = group.index.get(group.key(values))
                    except TypeError:
                        routes = None
                    for route in group.routes(values) if routes is None else routes:
                        value = route.get(values)
                        cls = value.__class__
                        if route.text:  # compared with strings: a string or nothing
                            if cls is not str and value is not None:
                                self._odd(route, valid, value, "a string")
                        elif cls is float:
                            if value - value:  # NaN or an infinity: unknown, never compared
                                value = None
                        elif cls is not int and cls is not bool:
                            value = self._odd(route, valid, value)
                        if strict:
                            self._constrain(route, available, valid)
                        if valid > max_valid:
                            max_valid = self.max_valid = valid
                        q = route.q
                        late = valid <= made
                        if late:
                            self.redo.add(q)  # the next state may read it: look again then
                            self._violation(
                                "late",
                                available,
                                route,
                                f"sample valid at {seconds(valid)} s arrived at "
                                f"{seconds(available)} s, after the state at "
                                f"{seconds(int(made))} s",
                            )
                        hist, rank = hists[q], route.rank
                        if hist and (
                            valid < hist[-1][0] or valid == hist[-1][0] and rank < hist[-1][1]
                        ):
                            bisect.insort(hist, (valid, rank, value), key=_VALID_RANK)
                            newest = hist[-1][0] == valid
                            if expiring and not newest:
                                self._stale_before_next(q, valid)
                                quiet = self.quiet_until
                        else:
                            hist.append((valid, rank, value))
                            newest = True
                        if periodic:
                            if self.next_state is None:
                                self.next_state = valid
                                quiet = self.quiet_until = valid + delay
                            continue
                        if not late:  # a state is due at its valid time, with q sampled at it
                            if not times or valid > times[-1]:
                                times.append(valid)
                                at.append([q])
                            elif valid == times[-1]:
                                at[-1].append(q)
                            else:
                                heapq.heappush(self.out_of_order, (valid, q))
                            if valid + delay < quiet:
                                quiet = self.quiet_until = valid + delay
                        if expiring and newest:
                            if due[q] >= valid and queued[q]:  # its expiry is queued already
                                due[q] = valid + stale_after
                            else:
                                self._expires(q, valid)
                                quiet = self.quiet_until
                        if limits and newest and q in limits:
                            self._deadline(q, valid)
                            quiet = self.quiet_until
                if watch is None:
                    continue
                n += 1
                seen = available
                if available > quiet:
                    self._emit(available, final=False)
                    quiet, made = self.quiet_until, self.made
                elif watching and available > quality.due:
                    # a topic declaring a rate went silent: seen at a message of any topic
                    # read, whether or not it makes a state (one standing by makes none)
                    self._report(quality.silent(available))
                if watch or not n & 4095:
                    self.last_seen = seen  # where a switch the caller makes now happens
                    yield n
                    # the caller may have fed the processor meanwhile (`_promote`)
                    max_valid, quiet, made = self.max_valid, self.quiet_until, self.made
        finally:
            self.read += n
            if seen is not None:
                self.last_seen = seen

    @staticmethod
    def _hold(groups: list[_Group], message: Message) -> None:
        """A message of a topic standing by: each route it would feed keeps it if newest."""
        for group in groups:
            for route in group.routes(message[3]):
                if route.held is None or message[2] >= route.held[2]:
                    route.held = message

    def _odd(
        self, route: _Route, valid: int, value: Any, wanted: str = "a number or boolean"
    ) -> Any:
        """A value that is not a plain number or boolean: a numeric subclass as it is, else an
        error naming the feature, the stream and the value's type."""
        if wanted != "a string":
            if isinstance(value, float | Decimal):
                return datum(float(value))
            if isinstance(value, numbers.Real):
                return value
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "…"
        raise DkError(
            f"{self.keys[route.q]} from {route.stream} at {seconds(valid)} s: "
            f"{type(value).__name__} {shown} is not {wanted}"
        )

    def advance(self, available: int) -> None:
        """Every source has passed `available`: make the states due by then (and set aside
        the topics silent too long by then)."""
        if self.quality.start is None:  # the stream clock starts: silence counts from it
            self.quality.begin(available)
        if available <= self.quiet_until and available <= self.quality.due:
            self.last_seen = available
            return  # nothing is due yet
        self._emit(available, final=False)

    def finish(self, end: int | None = None) -> None:
        """End of stream at `end` (the recording's last record time, of any topic: a value
        that went stale before it is unknown, however few topics were asked for), or at the
        end of the window if that comes first."""
        if end is not None and self.end is not None and self.placed:
            end = min(end, self.end)
        if end is not None and self.last_seen is not None:
            self.max_valid = max(self.max_valid, end)
            self.last_seen = max(self.last_seen, end)
        if self.last_seen is not None:
            self._emit(self.last_seen, final=True)

    def horizon(self) -> int | None:
        """Where the data ends (ns): the latest valid time seen (or the recording's end,
        once finished), no later than the window's end; None before any sample."""
        if self.max_valid < 0:
            return None
        return self.max_valid if self.end is None else min(self.max_valid, self.end)

    def _violation(self, kind: str, available: int, route: _Route, detail: str) -> None:
        self._report([(kind, self.keys[route.q], route.stream, available, detail)])

    def _report(self, found: list[Found]) -> None:
        origin = self.origin
        for kind, feature, stream, available, detail in found:
            self.on_violation(
                Violation(
                    kind,
                    seconds(available),
                    feature,
                    stream,
                    detail,
                    None if origin is None else seconds(available - origin),
                )
            )

    def _expires(self, q: int, valid: int) -> None:
        """Feature q's newest sample is valid at `valid`: it grows stale after max_age."""
        due = self.due
        if 0 <= due[q] < valid:  # the value went stale before this sample: keep that
            heapq.heappush(self.expiries, (due[q], q, True))
            self.quiet_until = min(self.quiet_until, due[q] + self.delay)
        due[q] = valid + self.stale_after
        if not self.queued[q]:
            self.queued[q] = True
            heapq.heappush(self.expiries, (due[q], q, False))
            self.quiet_until = min(self.quiet_until, due[q] + self.delay)

    def _stale_before_next(self, q: int, valid: int) -> None:
        """A sample of feature q came after a newer one: if the next sample is more than the
        maximum age later, q goes stale between them, at an instant no expiry waits for."""
        hist = self.hist[q]
        after = bisect.bisect_right(hist, valid, key=_VALID)
        if after < len(hist) and hist[after][0] > valid + self.stale_after:
            heapq.heappush(self.expiries, (valid + self.stale_after, q, True))
            self.quiet_until = min(self.quiet_until, valid + self.stale_after + self.delay)

    def _deadline(self, q: int, valid: int) -> None:
        """Feature q's newest sample is valid at `valid`: each age bound d over it turns d
        later (the heap holds one entry per offset: a queued one is moved on when it comes,
        `_passed`)."""
        for offset in self.limits[q]:
            if (q, offset) not in self.timed:
                self.timed.add((q, offset))
                heapq.heappush(self.deadlines, (valid + offset, q, offset))
                self.quiet_until = min(self.quiet_until, valid + offset + self.delay)

    def _passed(self, s: int, final: bool) -> list[FeatureKey]:
        """The features an age bound d over which turns at s: the newest sample valid by then
        is d old (at the end, not past the data).  Each entry taken moves on to when that
        sample, or the next one, grows that old."""
        out: list[FeatureKey] = []
        deadlines = self.deadlines
        while deadlines and deadlines[0][0] == s:
            _, q, offset = heapq.heappop(deadlines)
            if offset not in self.limits.get(q, ()):  # no formula reads it any more
                self.timed.discard((q, offset))
                continue
            hist = self.hist[q]
            i = bisect.bisect_right(hist, (s, 1)) - 1
            due = hist[i][0] + offset if i >= 0 else -1
            if due == s and not (final and s > self.max_valid):
                out.append(self.keys[q])
            later = due if due > s else hist[i + 1][0] + offset if i + 1 < len(hist) else None
            if later is None:
                self.timed.discard((q, offset))
            else:
                heapq.heappush(deadlines, (later, q, offset))
        return out

    def _constrain(self, route: _Route, available: int, valid: int) -> None:
        """The constraints on a sample (`strict`: a policy sets one)."""
        if self.max_delay is not None and available - valid > self.max_delay:
            self._violation(
                "max_delay",
                available,
                route,
                f"delay {seconds(available - valid)} s exceeds {seconds(self.max_delay)} s",
            )
        last = route.last
        if last is not None and (valid <= last and self.checks or self.period is not None):
            self._check(route, available, valid, last)
        if last is None or valid > last:
            route.last = valid

    def _check(self, route: _Route, available: int, valid: int, last: int) -> None:
        if valid < last and self.policy.ordered_on_valid_time:
            self._violation(
                "ordered_on_valid_time",
                available,
                route,
                f"valid time {seconds(valid)} s after {seconds(last)} s",
            )
        if valid == last and self.policy.unique_valid_time:
            self._violation(
                "unique_valid_time",
                available,
                route,
                f"second sample at valid time {seconds(valid)} s",
            )
        if (
            self.period is not None
            and valid > last
            and abs(valid - last - self.period) > self.deviation
        ):
            self._violation(
                "sample_period",
                available,
                route,
                f"{seconds(valid - last)} s since the previous sample, expected "
                f"{seconds(self.period)} ± {seconds(self.deviation)} s",
            )

    def _emit(self, now: int, final: bool) -> None:
        self.last_seen = now
        if self.quality.watched and now > self.quality.due:
            self._report(self.quality.silent(now))
        try:
            self.quiet_until = self._make_due(now, final)
        except BaseException:
            self.quiet_until = self._next_due()
            raise

    def _next_due(self) -> float:
        """The recording time after which the next state is due (inf: none is pending)."""
        if self.period is not None:
            return _INF if self.next_state is None else self.next_state + self.delay
        times, late, expiries = self.times, self.out_of_order, self.expiries
        head = times[0] if times else _INF
        if late and late[0][0] < head:
            head = late[0][0]
        if expiries and expiries[0][0] < head:
            head = expiries[0][0]
        if self.deadlines and self.deadlines[0][0] < head:
            head = self.deadlines[0][0]
        return head + self.delay

    def _make_due(self, now: int, final: bool) -> float:
        """Make the states due by `now`; returns `_next_due()`."""
        if self.period is not None:
            if not self.sized and self.next_state is not None:
                self._size(now, final)
            while self.next_state is not None and (final or self.next_state + self.delay < now):
                if final and self.next_state > self.max_valid:
                    break
                if self.end is not None and self.next_state > self.end:
                    break
                values, _ = self._every_value(self.next_state, None)
                self.made = self.next_state
                if self.terms:
                    self._terms(self.next_state, values)
                self.on_state(self.next_state, values, None)
                self.next_state += self.period
            return self._next_due()
        limit = None if final else now - self.delay  # make states strictly before this
        times, late, expiries, deadlines = (
            self.times,
            self.out_of_order,
            self.expiries,
            self.deadlines,
        )
        current, hists, keys, max_age, redo = (
            self.current,
            self.hist,
            self.keys,
            self.max_age,
            self.redo,
        )
        while True:
            s = times[0] if times else None
            if late and (s is None or late[0][0] < s):
                s = late[0][0]
            if expiries and (s is None or expiries[0][0] < s):
                s = expiries[0][0]
            if deadlines and (s is None or deadlines[0][0] < s):
                s = deadlines[0][0]
            if s is None or (limit is not None and s >= limit):
                return _INF if s is None else s + self.delay
            # everything due at s goes into one state, with the features sampled at s
            sampled: list[int] = _NO_QS
            if times and times[0] == s:
                times.popleft()
                sampled = self.at.popleft()
            while late and late[0][0] == s:
                sampled = [*sampled, heapq.heappop(late)[1]]
            stale, expired = (
                self._expired(s, final) if expiries and expiries[0][0] == s else _NO_EXPIRY
            )
            if deadlines and deadlines[0][0] == s:  # its readers' own, as for a stale value
                stale = [*stale, *self._passed(s, final)]
            opening = s == self.opening
            if not (sampled or stale or opening) or s <= self.made:
                continue
            if not self.incremental:
                values, fresh = self._every_value(s, stale)
            else:
                # A state made on every change differs from the one before only in the
                # features sampled at s, those a late sample reached and those whose expiry
                # fell at s (every other value is that of the same newest sample, no older):
                # only they are read, so a state costs what changed, not every feature.
                fresh = (*stale, *map(keys.__getitem__, sampled))  # a feature fed by two
                for q in (*sampled, *expired, *redo) if expired or redo else sampled:  # topics
                    hist = hists[q]  # at s appears twice
                    i = len(hist) - 1 if hist[-1][0] <= s else bisect.bisect_right(hist, (s, 1)) - 1
                    value = None
                    if i >= 0:
                        valid, _, v = hist[i]
                        if max_age is None or s - valid <= max_age:
                            value = v
                        if i > 32:
                            _prune(hist, i)
                    current[keys[q]] = value
                values = current
            if redo:  # a late sample is new to its readers: the state is theirs too
                if fresh is not None:
                    fresh = (*fresh, *map(keys.__getitem__, redo))
                redo.clear()
            self.made = s
            if opening:  # the start: every formula's state
                self.opening = fresh = None
            if self.terms:
                self._terms(s, values)
            self.on_state(s, values, fresh)

    def _size(self, now: int, final: bool) -> None:
        """Refuse a sample period that would make more than MAX_STATES states from the next
        one to where the stream ends: its end time or the recording's last record (checked
        once), or else to `now` (checked at each advance)."""
        assert self.period is not None and self.next_state is not None
        ends = [e for e in (self.end, self.recorded_end) if e is not None]
        upto = min(ends) if ends else self.max_valid if final else now - self.delay
        count = (upto - self.next_state) // self.period + 1
        if count > MAX_STATES:
            raise DkError(
                f"--period {seconds(self.period):g} s over {seconds(upto - self.next_state):g} s "
                f"would make {count:.2g} states (at most {MAX_STATES:,}): give a longer "
                f"period, or a shorter span (--start, --end)".replace("e+", "e")
            )
        self.sized = bool(ends)

    def _expired(self, s: int, final: bool) -> tuple[list[FeatureKey], list[int]]:
        """The features whose newest sample grows stale at s, and every feature whose expiry
        at s was taken (its value is read again)."""
        out, taken = [], []
        expiries = self.expiries
        while expiries and expiries[0][0] == s:
            _, q, fixed = heapq.heappop(expiries)
            if not fixed:
                if self.due[q] > s:  # newer samples moved the deadline: look again then
                    heapq.heappush(expiries, (self.due[q], q, False))
                    continue
                self.queued[q] = False
            taken.append(q)
            if not (final and s > self.max_valid) and self._stale(q, s):
                out.append(self.keys[q])
        return out, taken

    def newest(self, key: FeatureKey) -> int | None:
        """The valid time (ns) of the feature's newest sample (a term's: its feature's); None
        before its first."""
        hist = self.hist[self.terms[key][1] if key in self.terms else self.position[key]]
        return hist[-1][0] if hist else None

    def _stale(self, q: int, s: int) -> bool:
        """Whether feature q's newest sample at or before s is older than the maximum age."""
        hist = self.hist[q]
        i = bisect.bisect_right(hist, (s, 1)) - 1
        return i >= 0 and self.max_age is not None and s - hist[i][0] > self.max_age

    def _every_value(
        self, s: int, stale: list[FeatureKey] | None
    ) -> tuple[dict[FeatureKey, Any], tuple[FeatureKey, ...] | None]:
        """Each feature's value at s, read from its history."""
        values: dict[FeatureKey, Any] = {}
        fresh: list[FeatureKey] | None = (stale or []) if self.period is None else None
        recent, max_age, deviation = self.recent, self.max_age, self.deviation
        for key, hist in zip(self.keys, self.hist, strict=True):
            if hist and hist[-1][0] <= s:  # samples in order: the newest one
                i = len(hist) - 1
            else:  # the last sample valid at or before s
                i = bisect.bisect_right(hist, (s, 1)) - 1
            value = None
            if i >= 0:
                valid, _, v = hist[i]
                if valid == s and fresh is not None:
                    fresh.append(key)
                if recent:
                    if max_age is None or s - valid <= max_age:
                        value = v
                elif s - valid <= deviation:
                    value = v
                if i > 32:
                    _prune(hist, i)
            values[key] = value
        return values, None if fresh is None else tuple(fresh)
