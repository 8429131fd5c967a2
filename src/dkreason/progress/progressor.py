"""The Formula Progressor: formulas in, a state stream through, verdicts out as early as the
stream allows, never retracted.

    p = Progressor()
    p.add("always (Speed[car1] > 60 -> eventually[0, 300] Speed[car1] <= 60)")
    for time, values in states:          # values: FeatureKey → value
        for verdict in p.step(time, values): ...
    for verdict in p.finish(): ...

Formulas with quantifiers come from a plan (`KnowledgeManager.plan`), already expanded:
`p.add(f.text, f.tree)`.  The progressor knows nothing of knowledge bases.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from fractions import Fraction
from typing import Any

from ..errors import DkError
from ..inputs.numbers import exact
from ..model import FeatureKey
from ..parse.formula import Formula, feature_key, parse_formula, quantifiers
from .compile import Graph, scaled
from .fused import FusedSet, Held, Member, shapes
from .nodes import PENDING, Time, Why, fmt, why_of
from .state import features


@dataclass(frozen=True, slots=True)
class UnknownSpan:
    feature: FeatureKey
    start: Any
    end: Any

    def to_json(self) -> dict[str, Any]:
        return {
            "feature": str(self.feature),
            "from": _json_time(self.start),
            "to": _json_time(self.end),
        }


@dataclass(frozen=True, slots=True)
class Verdict:
    """The value of a formula at the first state, with the state that decided it.

    `at_end` is True when `finish()` settled it; `verdict` is None only then, when the data
    left it unknown (`unknown` says which features and when)."""

    formula: str
    verdict: bool | None
    time: Any
    at_end: bool
    witness: str | None = None
    unknown: tuple[UnknownSpan, ...] = field(default=())

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "formula": self.formula,
            "verdict": self.verdict,
            "time": _json_time(self.time),
            "at_end": self.at_end,
            "witness": self.witness,
        }
        if self.verdict is None:
            out["unknown"] = [u.to_json() for u in self.unknown]
        return out


def _json_time(t: Any) -> Any:
    if isinstance(t, Fraction | Decimal):
        return int(t) if t == int(t) else float(t)
    return t


def exact_time(t: Any) -> Time:
    """Times compared without floating-point error: 0.1 is 1/10, as written."""
    if type(t) is int:
        return t
    value = exact(t)
    return value.numerator if value.denominator == 1 else value


class _Monitor:
    """One formula: a fused step function, or the root of a shared node graph."""

    def __init__(self, text: str, keys: list[FeatureKey]) -> None:
        self.text, self.keys = text, keys
        self.value: Any = PENDING
        self.why: Why | None = None
        self.reported = False
        self.started = False
        self.first: Any = None  # time of the first state it judged
        self.graph: Graph | None = None
        self.node: Any = None
        self.members: list[Member] = []  # fused parts; the formula is their conjunction
        self.decided: list[_Monitor] = []  # the progressor's list of monitors to report

    def start(self, t: Time) -> None:
        assert self.graph is not None
        v = self.node.request(self.graph.ctx.pos, t, self, None)
        if v is not PENDING:
            self.deliver(None, v, why_of(self.node, t, v))

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        self.value, self.why = value, why
        self.decided.append(self)

    def false(self, why: Why) -> None:
        if self.value is PENDING:  # the first failing part decides
            self.deliver(None, False, why)


_UNSEEN: list[tuple[FeatureKey, Any]] = [(FeatureKey(""), object())]  # no state has this key


def _spelling(
    values: Mapping[Any, Any], keys: set[FeatureKey], time: Any
) -> list[tuple[FeatureKey, Any]]:
    """Each feature in `keys` and the key that stands for it in `values`: itself, or text
    (`"Close[uav1, uav2]"`), read here once per spelling, not once a state."""
    spelled = {k if isinstance(k, FeatureKey) else feature_key(k): k for k in values}
    missing = sorted(keys - spelled.keys())
    if missing:
        raise DkError(f"the state at time {time} has no value for {missing[0]}")
    return [(k, spelled[k]) for k in keys]


class Progressor:
    """`unit` is the seconds per unit of the times given to `step` (1; 1/10**9 for ns)."""

    def __init__(self, unit: Fraction | int = 1) -> None:
        self.unit = unit
        self.monitors: list[_Monitor] = []
        self.fused = FusedSet(self._note_unknowns, self)
        self.unstarted: list[_Monitor] = []
        self.decided: list[_Monitor] = []
        self.graphs: list[Graph] = []
        self.keys: set[FeatureKey] = set()
        self.pos = -1
        self.last_input: Any = None
        self.unknown: dict[FeatureKey, list[list[Any]]] = {}
        # what a state calls: `step_state`, or once every formula is fused and started, the
        # fused set's `fast` (the same, generated whole: one call a state), which holds
        # pos and last_input meanwhile (`held` reads them)
        self.stepper: Callable[..., Sequence[Verdict]] = self.step_state
        self.held: Held | None = None
        # `step`: the last time given, and how the caller spells each feature
        self.stepped: tuple[Time | float, Any] = (float("-inf"), None)
        self.spelling = _UNSEEN

    def add(self, formula: str, tree: Formula | None = None) -> None:
        """Compile a formula once (its quantifier-free `tree`, or the text parsed); it is
        judged from the next state on."""
        if tree is None:
            tree = parse_formula(formula)
            for q in quantifiers(tree):
                raise DkError(
                    f"{q.span}: quantifier over {q.sort} needs a knowledge base (give --config)"
                )
        parsed = scaled(tree, Fraction(1) / self.unit)
        self._general()  # the general step while this one is new
        monitor = _Monitor(formula, features(parsed))
        monitor.decided = self.decided
        parts = shapes(parsed)
        if parts is not None:
            monitor.members = [self.fused.add(p, monitor.false, self.unit) for p in parts]
        else:
            if not self.graphs or self.graphs[-1].ctx.pos >= 0:
                graph = Graph()
                graph.ctx.on_unknown = self._note_unknown
                graph.ctx.unit = self.unit
                self.graphs.append(graph)
            monitor.graph = self.graphs[-1]
            monitor.node = monitor.graph.node(parsed)
        self.monitors.append(monitor)
        self.unstarted.append(monitor)
        self.keys.update(monitor.keys)
        self.spelling = _UNSEEN

    def step(
        self, time: Any, values: Mapping[FeatureKey, Any] | Mapping[str, Any]
    ) -> list[Verdict]:
        """Feed one state; return the verdicts it decides.  Values are keyed by `FeatureKey`
        (as the stream processor makes them); keys written as text (`"Close[uav1, uav2]"`) are
        read at this boundary, once per spelling."""
        t = time if type(time) is int else exact_time(time)
        if not t > self.stepped[0]:
            raise DkError(
                f"time {time} is not after the previous state's time "
                f"{self.stepped[1]} (times must increase strictly)"
            )
        self.stepped = (t, time)
        typed = {}  # the features the formulas read, as the caller spells them
        try:
            for k, s in self.spelling:
                typed[k] = values[s]
        except KeyError:
            self.spelling = _spelling(values, self.keys, time)
            typed = {k: values[s] for k, s in self.spelling}
        return [*self.stepper(t, typed, time)]

    def step_state(
        self, t: Time, values: Mapping[FeatureKey, Any], given: Any = None
    ) -> list[Verdict]:
        """`step` for the stream processor's states, checked already: exact times that
        increase, every feature a value (`given`: the time as the caller wrote it)."""
        self.pos += 1
        self.last_input = t if given is None else given
        if self.unstarted:
            for m in self.unstarted:
                m.started, m.first = True, t
        fused = self.fused
        if fused.members:
            fused.step(t, values)
        if self.graphs:  # their nodes may explain themselves later: a copy of their own
            values = dict(values)
        for graph in self.graphs:
            ctx = graph.ctx
            if ctx.pos < 0:
                ctx.start = self.pos
            ctx.pos, ctx.now, ctx.values = self.pos, t, values  # type: ignore[assignment]
            for node in sorted(ctx.ticking, key=lambda n: n.level):
                node.tick()
        if self.unstarted:
            for m in self.unstarted:
                if m.node is not None:
                    m.start(t)
            self.unstarted = []
        elif fused.make is not None and not self.graphs:  # from the next state on, one call
            self.stepper, self.held = fused.make(self.pos, self.last_input)
        if not self.decided:
            return []
        return self._decided(at_end=False)

    def finish(self) -> list[Verdict]:
        """End of stream: settle every undecided formula by the finite-trace semantics."""
        for graph in self.graphs:
            for node in sorted(set(graph.cache.values()), key=lambda n: n.level):
                node.finish()
        self.fused.finish()
        self._general()
        for m in self.monitors:
            if m.value is not PENDING:
                continue
            if not m.started:
                m.deliver(None, None, None)
            elif m.members:
                unknown = any(part.unknown for part in m.members)
                m.deliver(None, None if unknown else True, None)
        self.fused.members = []
        return self._decided(at_end=True)

    def _general(self) -> None:
        """Back to `step_state`, with what the fast step held."""
        if self.held is not None:
            self.pos, self.last_input = self.held()
        self.stepper, self.held = self.step_state, None

    def _decided(self, at_end: bool) -> list[Verdict]:
        out = []
        order = {id(m): n for n, m in enumerate(self.monitors)}
        ready = sorted(self.decided, key=lambda m: order[id(m)])
        self.decided.clear()
        for m in ready:
            if m.reported:
                continue
            if m.value is None and not at_end:  # unknown for good: said at the end
                self.decided.append(m)
                continue
            m.reported = True
            witness = None
            if m.value is False and m.why is not None:
                if m.members:  # the fused step names the failing part only
                    witness = Why(
                        m.text, m.first, f"is false at {fmt(m.first, self.unit)}", m.why
                    ).render()
                else:  # the root node's reason, with the formula as the user wrote it
                    witness = Why(m.text, m.why.at, m.why.detail, m.why.cause).render()
            unknown: tuple[UnknownSpan, ...] = ()
            if m.value is None:
                unknown = tuple(
                    UnknownSpan(k, s[0], s[1]) for k in m.keys for s in self.unknown.get(k, ())
                )
                witness = "the data left it undecided: " + (
                    ", ".join(
                        f"{u.feature} unknown from {fmt(u.start, self.unit)} to "
                        f"{fmt(u.end, self.unit)}"
                        for u in unknown
                    )
                    if unknown
                    else "no state was seen"
                    if not m.started
                    else ""
                )
            out.append(Verdict(m.text, m.value, self.last_input, at_end, witness, unknown))
        return out

    def _note_unknowns(self, keys: list[FeatureKey]) -> None:
        for k in keys:
            self._note_unknown(k)

    def _note_unknown(self, key: FeatureKey) -> None:
        spans = self.unknown.setdefault(key, [])
        if spans and spans[-1][2] >= self.pos - 1:
            spans[-1][1], spans[-1][2] = self.last_input, self.pos
        elif not spans or spans[-1][2] != self.pos:
            spans.append([self.last_input, self.last_input, self.pos])


__all__ = ["Progressor", "UnknownSpan", "Verdict", "fmt"]
