"""Close the loop (thesis 2.3.2, 4.4): plan → stream request → Stream Processor → Formula
Progressor → verdicts.  One `Monitor` serves every caller: a recording (`run`), the live
federation (which feeds it samples and re-matches it as platforms come and go), the CLI and
`KnowledgeManager.monitor`.

    for event in km.monitor(["forall c in Car: always (Speed[c] > 60 -> "
                             "eventually[0, 300] Speed[c] <= 60)"], "traffic.mcap"): ...
"""

from __future__ import annotations

import dataclasses
import functools
import heapq
import itertools
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from operator import attrgetter, itemgetter
from typing import TYPE_CHECKING, Any, Protocol

from .errors import DkError
from .expand import Instance
from .judge import Judged, span_seconds, spans
from .model import FeatureKey, StreamRequest, stream_name
from .parse.formula import deadlines
from .plan import FormulaPlan, Plan
from .progress import Progressor, Verdict
from .progress.compile import scaled
from .progress.state import USE, feature_uses, fresh_limits, terms
from .progress.witness import Clock, Time, undecided
from .stream.pace import paced
from .stream.policy import StreamPolicy
from .stream.processor import StreamProcessor, Violation
from .stream.quality import Move
from .stream.sources import Source
from .stream.terms import term_key
from .stream.units import NS, seconds

if TYPE_CHECKING:  # robustness (numpy) is loaded when asked for: `match` needs none of it
    from .progress.kept import Kept


@dataclass(frozen=True, slots=True)
class Rerouted:
    """A feature read from other sources now: `source` (platform/topic) was set aside, its
    samples having stopped, or taken back, a sample having come (thesis 8.2's adaptive
    subscriptions); `before` and `after` are the feature's topics."""

    time: float | int  # s, on the stream's clock, like a violation's
    feature: FeatureKey
    source: str
    aside: bool
    before: tuple[str, ...]
    after: tuple[str, ...]
    reason: str
    t: float | int | None = None  # s from the start of the recording, exact

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"rerouted": str(self.feature), "time": self.time}
        if self.t is not None:
            out["t"] = self.t
        return out | {
            "source": self.source,
            "change": "set_aside" if self.aside else "taken_back",
            "before": list(self.before),
            "after": list(self.after),
            "reason": self.reason,
        }

    def __str__(self) -> str:
        what = "set aside" if self.aside else "taken back"
        return (
            f"{self.feature}: {self.source} {what} ({self.reason}); read from "
            f"{_topics(self.before)}, now from {_topics(self.after)}"
        )


def _topics(streams: tuple[str, ...]) -> str:
    return " + ".join(streams) or "no topic"


Event = Verdict | Violation | Rerouted
WORDS: dict[bool | None, str] = {True: "held", False: "violated", None: "unknown"}
"""How a verdict is said, by the CLI, the plot and whatever shows a person one."""
Watch = Callable[[int, dict[FeatureKey, Any], tuple[FeatureKey, ...] | None], None]
"""Told each state as it is made: its time (ns), the values, the features sampled at it
(None: any of them)."""


class Watcher(Protocol):
    """Who shows a run as it goes besides its reader (live/viewer.py: Foxglove): told each
    state and each event; `ready` returns when someone watches (a replay starts then)."""

    @property
    def url(self) -> str:
        """Where the run is watched."""
        ...

    def state(
        self, time: int, values: Mapping[FeatureKey, Any], fresh: tuple[FeatureKey, ...] | None
    ) -> None: ...

    def event(self, event: Any) -> None: ...

    def ready(self) -> None: ...

    def close(self) -> None: ...


class _Group:
    """The instances over one set of features, and the state stream they are judged on:
    formulas' (sharing it when they read the same features), or one quantified formula's."""

    def __init__(self, keys: frozenset[FeatureKey], formula: int | None) -> None:
        self.keys, self.formula = keys, formula
        self.progressor: Progressor
        # with robustness: the states it was judged at that a margin may still read (what
        # its formulas read of them)
        self.kept: Kept | None = None


Unit = tuple[int, int]  # an instance being judged: (formula, instance) in the plan
Timers = list[tuple[Time, int, _Group]]  # a heap: (deadline in ns, ticket, group)


class Monitor:
    """A plan (formulas parsed, checked and expanded once) and the match that binds it to
    streams (asked again by `rematch` when the knowledge changes); states in, verdicts out.

    Each instance of a formula (judge.py) is judged on its own state stream: from the first
    state at which every feature it reads has a value (a recording's warm-up is not
    "unknown", and one silent object blinds no other; with a start time, from the state made
    at it, its atoms over features without a value unknown there), at the instants its own
    features are sampled or change, and when the stream of its formula's features passes the
    end of a window it waits on.  Formulas over the same features share one progressor (the
    instances of a quantified formula with bounded windows, only among themselves).

    A topic declaring a rate whose samples stop for `policy.set_aside_after` periods is set
    aside (the rules are told `degraded(Platform, Topic)`) and taken back at its next sample:
    the plan is matched again between messages, the instances judged on as they were, and
    each feature whose topics changed is a `Rerouted` event."""

    def __init__(
        self,
        plan: Plan,
        match: Callable[..., StreamRequest],
        policy: StreamPolicy,
        *,
        keep_states: bool = False,
        robustness: bool = False,
        watch: Watch | None = None,
    ) -> None:
        """`match(plan)`: the stream request (with `degraded=` the sources set aside, once
        one is: `KnowledgeManager.request`'s); `keep_states`: every state kept (`states`, for
        a plot); `watch`: told each one."""
        self.plan, self.match, self.policy = plan, match, policy
        self.aside: set[tuple[str, str]] = set()  # (platform, topic)s whose samples stopped
        self.moved = False  # a source was set aside or taken back: match again (`events`)
        # told the request after a source set aside or taken back (a live monitor follows it)
        self.follow: Callable[[StreamRequest], list[Any]] | None = None
        self.watchers: list[Watch] = [self._keep] if keep_states else []
        if watch is not None:
            self.watchers.append(watch)
        # robustness: each group keeps the states its instances' margins may read (`Kept`,
        # trees in stream units), each instance its group (`_margin`); Boolean monitoring
        # does none of it
        self.robust = robustness
        self.begun: dict[str, _Group] = {}
        self._sources: dict[FeatureKey, str] | None = None
        self.request = match(plan)
        self.said: set[str] = set()  # the request's warnings `unsaid` gave
        self.judged = [Judged(f) for f in plan.formulas]
        self.groups: dict[frozenset[FeatureKey], _Group] = {}
        # A state is a group's own when one of its features was sampled or went stale at it
        # (every state with a sample period, and for a group reading no feature): the groups
        # each feature makes due, in the order the groups began.
        self.readers: dict[FeatureKey, list[_Group]] = {}
        self.always: list[_Group] = []
        # the due groups' progressors by the features a state freshly sampled (`_due`)
        self.steps: dict[tuple[FeatureKey, ...] | None, list[Progressor]] = {}
        self.rearm: list[_Group] = []  # advanced: asked by when their next window ends
        # A quantified formula's instances are judged on their own features' states, yet the
        # stream passing a window's end without one (a state of another instance) closes it:
        # its instances' groups say by when (`timers`, per formula), and are advanced to
        # states of the formula's features that are not theirs.
        self.timers: dict[int, Timers] = {}
        self.timed: dict[FeatureKey, list[int]] = {}  # feature → the quantified formulas reading it
        self.tickets = itertools.count()
        self.units: dict[str, Unit] = {}  # an instance's name in its progressor → its unit
        self.waiting: dict[Unit, Instance] = {}  # not begun: some feature had no value yet
        self.waits_on: dict[FeatureKey, list[Unit]] = {}  # the waiting units reading each
        # what a waiting unit needs known to begin: its features, and its terms over samples
        # (`rate(X)` waits for X's second sample)
        self.needs: dict[Unit, tuple[FeatureKey, ...]] = {}
        for n, f in enumerate(plan.formulas):
            self._wait(n, range(len(f.instances)), f.instances)
            self._time(n, f)
        if policy.start_time is not None:
            self._begin(list(self.waiting))
        self.seen = False  # a state was made
        self.states: list[tuple[int, dict[FeatureKey, Any]]] = []
        self.pending: list[Any] = []  # events, and sources set aside or taken back (Move)
        self.processor: StreamProcessor | None = None
        self.source: Source | None = None

    def origin(self) -> int | None:
        """The start of the recording(s) (ns; None until known): `t` and `t+` count from it."""
        return None if self.processor is None else self.processor.origin

    def start(self, source: Source) -> StreamProcessor:
        """The stream processor over `source`, states going to the progressor; each feature's
        use in the formulas is checked against its fields' types before any message."""
        used = self._uses()
        self.source = source
        self.processor = StreamProcessor(
            self.request,
            self.policy,
            source,
            self._on_state,
            self.pending.append,
            frozenset(k for k, (use, _) in used.items() if use == "string"),
            self._terms(),
            self._moved,
            self._limits(),
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

    def _uses(self) -> dict[FeatureKey, tuple[str, str]]:
        return feature_uses((f.text, i.tree) for f in self.plan.formulas for i in f.instances)

    def _terms(self) -> set[tuple[str, FeatureKey]]:
        """The terms over samples the formulas read (`prev(X)`): the states carry them."""
        return {t for f in self.plan.formulas for i in f.instances for t in terms(i.tree)}

    def _limits(self) -> set[tuple[FeatureKey, Fraction]]:
        """The ages the formulas' truth turns at (`fresh(X, d)`, `age(X) <= d`): a state is made
        when X's last sample grows that old."""
        return {x for f in self.plan.formulas for i in f.instances for x in fresh_limits(i.tree)}

    def _keep(self, time: int, values: dict[FeatureKey, Any], _: object) -> None:
        self.states.append((time, dict(values)))

    def _wait(self, n: int, indices: Iterable[int], instances: Sequence[Instance]) -> None:
        for i, instance in zip(indices, instances, strict=True):
            self.waiting[(n, i)] = instance
            self.needs[(n, i)] = (
                *instance.keys,
                *(term_key(op, k) for op, k in sorted(terms(instance.tree)) if op != "age"),
            )
            for k in instance.keys:
                self.waits_on.setdefault(k, []).append((n, i))

    def _time(self, n: int, formula: FormulaPlan) -> None:
        """A quantified formula that waits on bounded windows gets timers; any other shares
        groups with the formulas over the same features (nothing but its own states decides
        it)."""
        if formula.prefix and any(deadlines(i.tree) for i in formula.instances[:1]):
            self.timers.setdefault(n, [])
            for k in formula.keys:
                if n not in self.timed.setdefault(k, []):
                    self.timed[k].append(n)

    def _begin(self, units: list[Unit]) -> None:
        for unit in sorted(units):
            instance = self.waiting.pop(unit)
            del self.needs[unit]
            keys = frozenset(instance.keys)
            quantified = unit[0] if unit[0] in self.timers else None
            at: Any = keys if quantified is None else (quantified, keys)
            group = self.groups.get(at)
            if group is None:
                group = self.groups[at] = _Group(keys, quantified)
                group.progressor = Progressor(
                    Fraction(1, NS),
                    end_of_data=self.policy.end_of_data,
                    origin=self.origin,
                    timer=None if quantified is None else functools.partial(self._arm, group),
                )
                for k in keys:
                    self.readers.setdefault(k, []).append(group)
                if not keys:
                    self.always.append(group)
            name = f"{unit[0]}:{unit[1]}"
            self.units[name] = unit
            group.progressor.add(name, instance.tree)
            if self.robust:
                if group.kept is None:
                    from .progress.kept import Kept

                    group.kept = Kept()
                group.kept.add(name, scaled(instance.tree, Fraction(NS)))
                self.begun[name] = group
        self.steps.clear()

    def _arm(self, group: _Group, deadline: Time) -> None:
        assert group.formula is not None
        heapq.heappush(self.timers[group.formula], (deadline, next(self.tickets), group))

    def _advance(self, heap: Timers, time: int, due: list[Progressor]) -> list[Verdict]:
        """The groups of one quantified formula whose windows ended by `time` (a state of its
        features): those it is not a state of are advanced to it, and all asked again by when
        their next window ends (after their own state, for those it is one of)."""
        out: list[Verdict] = []
        again = []
        while heap and heap[0][0] <= time:
            group = heapq.heappop(heap)[2]
            if group.progressor not in due:
                out += group.progressor.advance(time)
            again.append(group)
        self.rearm += again
        return out

    def _ready(self, values: dict[FeatureKey, Any], fresh: tuple[FeatureKey, ...] | None) -> None:
        """The waiting instances whose every feature has a value now begin (`fresh` None:
        look at all, else at those reading a feature sampled now)."""
        if fresh is None:
            candidates: Iterable[Unit] = list(self.waiting)
        else:
            candidates = {u for k in fresh for u in self.waits_on.get(k, ())}
        ready = [
            u
            for u in candidates
            if u in self.waiting and all(values[k] is not None for k in self.needs[u])
        ]
        if ready:
            read = {k for u in ready for k in self.waiting[u].keys}
            self._begin(ready)
            for k in read:
                left = [u for u in self.waits_on[k] if u in self.waiting]
                if left:
                    self.waits_on[k] = left
                else:
                    del self.waits_on[k]

    def _on_state(
        self, time: int, values: dict[FeatureKey, Any], fresh: tuple[FeatureKey, ...] | None = None
    ) -> None:
        if self.watchers:
            for watch in self.watchers:
                watch(time, values, fresh)
        if not self.seen:  # the first state: every group's with a start time, and where
            self.seen = True  # formulas over no feature (or an empty sort) are judged
            if self.policy.start_time is not None:
                fresh = None
            self._ready(values, None)
            for judged in self.judged:
                if not judged.names:
                    self.pending.extend(judged.settle((), self._when(time)))
        elif self.waiting:
            self._ready(values, fresh)
        steps = self.steps.get(fresh)
        if steps is None:
            if len(self.steps) >= 1024:  # many features sampled in many combinations
                self.steps.clear()
            steps = self.steps[fresh] = [g.progressor for g in self._due(fresh)]
        if self.robust:
            for g in self._due(fresh):
                if g.kept is not None:  # a group of robust formulas' instances
                    g.kept.append(time, values)
        decided: Sequence[Verdict] = self._timers(fresh, time, steps) if self.timers else ()
        for progressor in steps:  # its stepper changes as formulas are decided
            out = progressor.stepper(time, values)
            if out:
                decided = [*decided, *out]
        if self.rearm:
            for group in self.rearm:
                deadline = group.progressor.deadline()
                if deadline is not None:
                    self._arm(group, deadline)
            self.rearm = []
        if decided:
            self._settled([(v, None) for v in decided], self._when(time), at_end=False)

    def _timers(
        self, fresh: tuple[FeatureKey, ...] | None, time: int, due: list[Progressor]
    ) -> list[Verdict]:
        """At a state of quantified formulas' features: their groups whose windows ended by
        then, advanced (`_advance`)."""
        formulas = (
            self.timers if fresh is None else {n for k in fresh for n in self.timed.get(k, ())}
        )
        out: list[Verdict] = []
        for n in sorted(formulas):
            heap = self.timers[n]
            if heap and heap[0][0] <= time:
                out += self._advance(heap, time, due)
        return out

    def _due(self, fresh: tuple[FeatureKey, ...] | None) -> Iterable[_Group]:
        """The groups whose own state this is, in the order they began."""
        if fresh is None:
            return self.groups.values()
        if len(fresh) == 1 and not self.always:
            return self.readers.get(fresh[0], ())
        return [g for g in self.groups.values() if not g.keys or not g.keys.isdisjoint(fresh)]

    def _when(self, ns: int | None) -> tuple[Any, Any]:
        """A stream time (ns) as a verdict says it: on the recording's clock and as `t`, s."""
        origin = self.origin()
        if ns is None:
            return None, None
        return seconds(ns), None if origin is None else seconds(ns - origin)

    def _settled(
        self, decided: Iterable[tuple[Verdict, Any]], now: tuple[Any, Any], at_end: bool
    ) -> None:
        """Instance verdicts (from a progressor, times in ns; with the time of their group's
        last state when settled at the end) to the formulas they decide, in formula order."""
        batches: dict[int, list[tuple[int, Verdict]]] = {}
        for v, last in decided:
            n, i = self.units[v.formula]
            if self.robust:
                v = dataclasses.replace(v, robustness=self._margin(v, at_end))
            batches.setdefault(n, []).append((i, self._seconds(v, last)))
        for n in sorted(batches) if not at_end else range(len(self.judged)):
            judged = self.judged[n]
            if n in batches or judged.said is None:
                batch = sorted(batches.get(n, ()), key=itemgetter(0))
                self.pending.extend(judged.settle(batch, now, at_end))

    def _margin(self, v: Verdict, at_end: bool) -> Any:
        """An instance's robustness over the states it was judged at, up to its verdict's;
        a window reaching past the data seen then (or past the end of the data, unless every
        window closes at the last state) unknown in its unseen part."""
        from .progress.robustness import UNKNOWN, margin

        group = self.begun.pop(v.formula, None)
        if group is None:
            return UNKNOWN  # never observed
        upto = end = v.time
        if at_end:
            assert self.processor is not None
            end = self.processor.horizon() if self.policy.end_of_data == "open" else None
        assert group.kept is not None
        found = group.kept.margin(v.formula, upto, end)
        return margin(found, Clock(Fraction(1, NS), self.origin), self.sources(), seconds)

    def sources(self) -> dict[FeatureKey, str]:
        """Where each feature's values are read, as a margin names it: `platform/topic field`,
        and what the topic's specification calls it when that differs (an equivalent
        feature, another platform's names: `via Alt[uas21]`); merged topics joined by `or`."""
        if self._sources is None:
            self._sources = {}
            for f in self.request.features:
                k = f.feature.key
                self._sources[k] = " or ".join(
                    f"{stream_name(t.platform, t.topic)} {t.field}"
                    + (
                        ""
                        if (t.as_feature, t.as_args) == (k.name, k.args)
                        else f" via {t.as_feature}[{', '.join(t.as_args)}]"
                    )
                    for t in f.topics
                )
        return self._sources

    def _seconds(self, v: Verdict, last: int | None) -> Verdict:
        """A progressor's verdict in seconds, on the recording's clock (`time`) and from its
        start (`t`, exact: the difference is taken in nanoseconds); an unknown one's spans as
        people read them:
        those closer than the maximum age merged, one that lasts to the end said as a source
        gone silent (or never observed)."""
        origin = self.origin()
        v = dataclasses.replace(
            v,
            time=None if v.time is None else seconds(v.time),
            t=None if v.time is None or origin is None else seconds(v.time - origin),
            window=None if v.window is None else (seconds(v.window[0]), seconds(v.window[1])),
        )
        if v.verdict is not None or last is None:
            return v
        assert self.processor is not None
        end = self.processor.horizon()
        unknown = spans(v.unknown, last, end, self.processor.newest, self.processor.max_age)
        clock = Clock(Fraction(1, NS), self.origin)
        witness = undecided(unknown, True, clock, v.pending)
        return dataclasses.replace(v, unknown=tuple(map(span_seconds, unknown)), witness=witness)

    @property
    def done(self) -> bool:
        """Every formula decided and every instance of it settled."""
        return all(j.said is not None and not j.open for j in self.judged)

    def events(self) -> list[Event]:
        """What was decided or violated since the last call, and the features read from
        other sources since (a source set aside or taken back: matched again here, between
        messages)."""
        out, self.pending[:] = list(self.pending), []
        if self.moved:
            self.moved = False
            out = [e for event in out for e in self._rerouted(event)]
        if len(out) > 1 and all(e.time is not None for e in out):
            # in the order of their times: a message's checks come before the states it lets
            # the stream make, which may be earlier (a deadline's, a late sample's)
            out.sort(key=attrgetter("time"))
        return out

    def _moved(self, move: Move) -> None:
        self.moved = True
        self.pending.append(move)

    def _rerouted(self, event: Any) -> list[Any]:
        """A source set aside or taken back (else `event` as it is): the plan matched again
        without it or with it; a line per feature whose topics changed (what a live monitor
        following the request says after them)."""
        if not isinstance(event, Move):
            return [event]
        assert self.source is not None
        source = (event.platform, event.topic)
        if event.aside:
            self.aside.add(source)
        else:
            self.aside.discard(source)
        before = _streams(self.request)
        after = _streams(self.rematch(self.source))
        origin = self.origin()
        out: list[Any] = [
            Rerouted(
                seconds(event.time),
                key,
                stream_name(event.platform, event.topic),
                event.aside,
                before.get(key, ()),
                topics,
                event.reason,
                None if origin is None else seconds(event.time - origin),
            )
            for key, topics in after.items()
            if topics != before.get(key, ())
        ]
        if self.follow is not None:
            out += self.follow(self.request)
        return out

    def extend(self, plan: Plan) -> list[tuple[str, str]]:
        """The same formulas planned again on changed knowledge: the instances of objects that
        joined their sorts are judged from now on (as the others were from the start), every
        other instance goes on as it was.  Returns (formula, instance) of each new one; call
        `rematch` next, so their features are streamed."""
        formulas, started = [], []
        for n, (old, new) in enumerate(zip(self.plan.formulas, plan.formulas, strict=True)):
            judged = self.judged[n]
            fresh = tuple(i for i in new.instances if i.bindings not in judged.index)
            if not fresh:
                formulas.append(old)
                continue
            prefix = tuple(
                dataclasses.replace(
                    b, objects=(*b.objects, *(o for o in c.objects if o not in b.objects))
                )
                for b, c in zip(old.prefix, new.prefix, strict=True)
            )
            grown = FormulaPlan(old.text, prefix, (*old.instances, *fresh), old.warnings)
            formulas.append(grown)
            self._time(n, grown)
            indices = judged.extend(grown)
            self._wait(n, indices, fresh)
            started += [(old.text, ", ".join(f"{v} = {o}" for v, o in i.bindings)) for i in fresh]
            if self.policy.start_time is not None:
                self._begin([(n, i) for i in indices])
        self.plan = Plan(tuple(formulas))
        self.steps.clear()
        return started

    def unsaid(self) -> list[str]:
        """The current request's warnings not given before: what a live monitor, matching
        again as its federation changes, says once (an exclusion, a window too fine)."""
        new = [w for w in self.request.warnings if w not in self.said]
        self.said.update(new)
        return new

    def rematch(self, source: Source) -> StreamRequest:
        """The plan's features matched again (the knowledge changed); the streams follow."""
        assert self.processor is not None
        aside = frozenset(self.aside)
        self.request = self.match(self.plan, degraded=aside) if aside else self.match(self.plan)
        self._sources = None
        self.processor.texts = frozenset(
            k for k, (use, _) in self._uses().items() if use == "string"
        )
        self.processor.reroute(self.request, source)
        self.processor.want(self._terms(), self._limits())
        return self.request

    def finish(self, end: int | None = None) -> list[Event]:
        """End of stream (at `end`, ns, when known): every formula settled."""
        assert self.processor is not None
        self.processor.finish(end)
        horizon = self.processor.horizon()
        settled = [
            (v, g.progressor.last_input)
            for g in self.groups.values()
            for v in g.progressor.finish(horizon)
        ]
        for unit, instance in self.waiting.items():  # some feature never had a value
            name = f"{unit[0]}:{unit[1]}"
            self.units[name] = unit
            missing = ", ".join(str(k) for k in instance.keys if self.processor.newest(k) is None)
            settled.append(
                (
                    Verdict(
                        name,
                        None,
                        None,
                        True,
                        "no state had a value for every feature it reads"
                        + (f" (never seen: {missing})" if missing else ""),
                    ),
                    None,
                )
            )
        self.waiting.clear()
        self._settled(settled, self._when(horizon), at_end=True)
        return self.events()

    def run(
        self, source: Source, progress: Callable[[int], None] | None = None, speed: float = 0
    ) -> Iterator[Event]:
        """Events as they happen: violations as seen, verdicts as decided, the rest at the end.
        An error in the source comes after every event decided before it.  `speed`: the
        messages replayed at that many times their record times' pace (0: at once)."""
        try:
            processor = self.processor or self.start(source)
        except BaseException:
            source.close()
            raise
        pending = self.pending
        try:
            messages = source.messages(processor.wanted)
            for n in processor.replay(paced(messages, speed) if speed else messages, pending):
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
    iterated (once), it yields the events as they happen, its messages replayed at `speed`
    times their pace (0: at once) and shown to `watcher` (once it is `ready`).  Left unread,
    close it (or use it in a `with` block); a watcher is served until the run is closed."""

    def __init__(
        self, monitor: Monitor, source: Source, *, speed: float = 0, watcher: Watcher | None = None
    ) -> None:
        self.monitor, self.source, self.speed, self.watcher = monitor, source, speed, watcher
        try:
            self.processor = monitor.start(source)
        except BaseException:
            self.close()
            raise
        if watcher is not None:
            monitor.watchers.append(watcher.state)

    @property
    def request(self) -> StreamRequest:
        return self.monitor.request

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the formulas probably do not mean, one line each (the request's first)."""
        return self.monitor.plan.warnings

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
        if self.watcher is None:
            return self.monitor.run(self.source, progress, self.speed)
        return self._watched(self.watcher, progress)

    def _watched(self, watcher: Watcher, progress: Callable[[int], None] | None) -> Iterator[Event]:
        watcher.ready()
        for event in self.monitor.run(self.source, progress, self.speed):
            watcher.event(event)
            yield event

    def __iter__(self) -> Iterator[Event]:
        return self.events()

    def close(self) -> None:
        """The sources closed without reading on (iterating to the end closes them too),
        the watcher no longer served."""
        self.source.close()
        if self.watcher is not None:
            self.watcher.close()

    def __enter__(self) -> MonitorRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _streams(request: StreamRequest) -> dict[FeatureKey, tuple[str, ...]]:
    """Each feature's topics, as people read them (`platform/topic`, `platform:/topic`)."""
    return {
        f.feature.key: tuple(dict.fromkeys(stream_name(t.platform, t.topic) for t in f.topics))
        for f in request.features
    }


def _joined(before: tuple[str, ...], now: tuple[str, ...]) -> tuple[str, ...]:
    return (*before, *(o for o in now if o not in before))


def _article(kind: str, ros_type: str) -> str:
    if kind in ("message", "array"):
        return "a sub-message" if kind == "message" else "an array"
    return f"a{'n' if ros_type[0] in 'aeiou' else ''} {ros_type}"
