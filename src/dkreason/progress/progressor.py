"""The Formula Progressor: formulas in, a state stream through, verdicts out as early as the
stream allows, never retracted.

    p = Progressor()
    p.add("always (Speed[car1] > 60 -> eventually[0, 300] Speed[car1] <= 60)")
    for time, values in states:          # values: FeatureKey → value
        for verdict in p.step(time, values): ...
    for verdict in p.finish(): ...

Formulas with quantifiers come from a plan (`KnowledgeManager.plan`), already expanded:
`p.add(f.text, f.tree)`.  The progressor knows nothing of knowledge bases.

Each top-level conjunct of a formula (a part) goes to one of two engines behind one contract
(engine.py): the generated fused monitors (fused.py) when they take its shape, the general
node graph (general.py) otherwise or always (`engine="general"`).  Both give the same
verdicts at the same states with the same witnesses (witness.py).

The end of the data: `finish(end)` settles what is left.  A bounded window (`eventually[0, 5]`,
`always[0, 5]`, `until[0, 5]`, `next[0, 5]`) reaching past the end of the data is left
undecided (`verdict` None, its `pending` text says which window and how much of it was seen):
no violation is claimed past the data.  Unbounded operators keep their finite-trace values
(`always` holds, an unmet `eventually` fails), as every window does with
`end_of_data="finite"`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping, Sequence
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from ..errors import DkError
from ..inputs.numbers import exact
from ..model import FeatureKey
from ..parse.formula import (
    Connective,
    Formula,
    feature_key,
    formula_warnings,
    parse_formula,
    quantifiers,
)
from ..stream.policy import END_OF_DATA
from ..stream.terms import Samples
from .compile import scaled
from .engine import Engine, Entry, Held, Report, Stepper, Timer
from .fused import Direct, FusedSet
from .general import General
from .state import base_features, features, is_state, terms
from .verdict import Margin, UnknownSpan, Verdict
from .witness import Clock, Time, Why, cut_of, refuted, since, undecided

if TYPE_CHECKING:  # robustness (numpy) is loaded when asked for
    from .kept import Kept

ENGINES = ("auto", "general")


def exact_time(t: Any) -> Time:
    """Times compared without floating-point error: 0.1 is 1/10, as written."""
    if type(t) is int:
        return t
    value = exact(t)
    return value.numerator if value.denominator == 1 else value


class _Formula:
    """One formula: the Kleene conjunction of its parts' values, as the engines report them.
    When several parts fail at one state, the leftmost is the witness (both engines alike)."""

    def __init__(self, text: str, keys: list[FeatureKey], decided: list[_Formula]) -> None:
        self.text, self.keys, self.decided = text, keys, decided
        self.open = 0  # parts not reported yet
        self.value: bool | None = True  # so far
        self.why: Why | None = None
        self.failed = -1  # the part that is the witness
        self.cut: tuple[int, Why] | None = None  # the leftmost part a cut window left open
        self.queued = False  # in `decided`, to be reported
        self.reported = False
        self.started = False

    def report(self, part: int) -> Report:
        self.open += 1
        return functools.partial(self.part, part)

    def part(self, n: int, value: bool | None, why: Why | None) -> None:
        self.open -= 1
        if self.reported:
            return
        if value is False and (self.value is not False or n < self.failed):
            self.value, self.why, self.failed = False, why, n
        elif value is None:
            if self.value is True:
                self.value = None
            cut = cut_of(why)
            if cut is not None and (self.cut is None or n < self.cut[0]):
                self.cut = (n, cut)
        if (self.value is False or not self.open) and not self.queued:
            self.queued = True
            self.decided.append(self)


def conjuncts(f: Formula) -> list[Formula]:
    """The top-level conjuncts of `f`, left to right (a `forall` expands to them); a state
    formula stays whole (one check of the state, its witness every value it read)."""
    out: list[Formula] = []
    todo = [f]
    while todo:
        g = todo.pop()
        if isinstance(g, Connective) and g.op == "and" and not is_state(g):
            todo += [g.right, g.left]
        else:
            out.append(g)
    return out


_UNSEEN: list[tuple[FeatureKey, Any]] = [(FeatureKey(""), object())]  # no state has this key


def _spelling(
    values: Mapping[Any, Any], keys: set[FeatureKey], time: Any
) -> list[tuple[FeatureKey, Any]]:
    """Each feature in `keys` and the key that stands for it in `values`: itself, or text
    (`"Close[uav1, uav2]"`), read here once per spelling, not once a state."""
    spelled = {k if isinstance(k, FeatureKey) else feature_key(k): k for k in values}
    missing = sorted(keys - spelled.keys())
    if missing:
        raise DkError(
            f"the state at time {time} has no value for {missing[0]} "
            f'(write "{missing[0]}": null for a value not known then)'
        )
    return [(k, spelled[k]) for k in keys]


class Progressor:
    """`unit` is the seconds per unit of the times given to `step` (1; 1/10**9 for ns).
    `engine`: "auto" gives each part of a formula to the fused monitors when they take its
    shape and to the general engine otherwise; "general" gives every part to the general
    engine (the same verdicts, times and witnesses, more slowly).  `end_of_data`: "open"
    leaves a bounded window that the end of the data cuts off undecided, "finite" closes it
    (module docstring).  `origin`: when given, witnesses say times as `t+…` seconds from the
    stream time it returns (the run's start).  `timer`: told by when a window will have ended
    (in the stream's times), so a caller that sees the stream pass it without a state of these
    formulas can `advance` to it.  `robustness`: each verdict of a state given to `step` says
    by how much (progress.robustness), from the states `step` keeps for it."""

    def __init__(
        self,
        unit: Fraction | int = 1,
        engine: str = "auto",
        end_of_data: str = "open",
        origin: Callable[[], Time | None] | None = None,
        timer: Timer | None = None,
        robustness: bool = False,
    ) -> None:
        if engine not in ENGINES:
            raise DkError(f"unknown engine {engine!r} ({' or '.join(ENGINES)})")
        if end_of_data not in END_OF_DATA:
            raise DkError(f"unknown end of data {end_of_data!r} ({' or '.join(END_OF_DATA)})")
        self.unit, self.end_of_data = unit, end_of_data
        self.clock = Clock(unit, origin)
        self.fused = FusedSet(self.clock, self.note_unknown, timer)
        self.general = General(self.clock, self.note_unknown, timer)
        self.engines: tuple[Engine, ...] = (
            (self.fused, self.general) if engine == "auto" else (self.general,)
        )
        self.formulas: list[_Formula] = []
        self.warnings: list[str] = []  # of the formulas added as text (parse.self_comparisons)
        self.unstarted: list[_Formula] = []
        self.decided: list[_Formula] = []
        self.keys: set[FeatureKey] = set()  # what `step` reads from the caller's states
        self.samples = Samples(unit)  # the terms over samples `step` writes into them
        # robustness: the states `step` was given that a formula's margin may still read
        self.kept: Kept | None = None
        if robustness:
            from .kept import Kept

            self.kept = Kept()
        # what `step` does with a state besides judging it (one test a state when nothing)
        self.keeping: Callable[[Time, dict[FeatureKey, Any]], None] | None = (
            None if self.kept is None else self.kept.append
        )
        self.pos = -1
        self.last_input: Any = None
        self.unknown: dict[FeatureKey, list[list[Any]]] = {}
        # what a state calls: `step_state`, or while every part is fused, the fused set's
        # `fast` (the same, generated whole: one call a state), which holds pos and
        # last_input meanwhile (`held` reads them)
        self.stepper: Stepper[Verdict] = self.step_state
        self.held: Held | None = None
        # what `step` calls: `_checked`, or while every part is fused (and no term over
        # samples is written into the states), the fused set's `entry`, which holds them
        # and the last time given, and keeps the states for robustness (`stepper` is then
        # `_handed`)
        self.entry: Entry = self._checked
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
            self.warnings += formula_warnings(tree)
        parsed = scaled(tree, Fraction(1) / self.unit)
        self._general()  # the general step while this one is new
        judged = _Formula(formula, features(parsed), self.decided)
        for n, part in enumerate(conjuncts(parsed)):
            report = judged.report(n)
            next(e for e in self.engines if e.add(part, report))
        if self.kept is not None:
            self.kept.add(id(judged), parsed)
            self.fused.keeps = list(self.kept.columns)
        self.formulas.append(judged)
        self.unstarted.append(judged)
        self.keys.update(base_features(parsed))
        self.samples.want(terms(parsed))
        if self.samples.terms:
            self.keeping = self._keep
        self.spelling = _UNSEEN

    def step(
        self, time: Any, values: Mapping[FeatureKey, Any] | Mapping[str, Any]
    ) -> list[Verdict]:
        """Feed one state; return the verdicts it decides.  Values are keyed by `FeatureKey`
        (as the stream processor makes them); keys written as text (`"Close[uav1, uav2]"`) are
        read at this boundary, once per spelling.  Each state where a feature has a value is a
        sample of it (`prev(X)` is its value at the last such state before)."""
        return self.entry(time, values)

    def _checked(
        self, time: Any, values: Mapping[FeatureKey, Any] | Mapping[str, Any]
    ) -> list[Verdict]:
        """`step` in general: the time checked and made exact, the features read through
        their spelling; the fused fast step's `entry` does the same, generated."""
        t = time if type(time) is int else exact_time(time)
        if not t > self.stepped[0]:
            raise DkError(
                f"time {time} is not after the previous state's time "
                f"{self.stepped[1]} (times must increase strictly)"
            )
        typed = {}  # the features the formulas read, as the caller spells them
        try:
            for k, s in self.spelling:
                typed[k] = values[s]
        except KeyError:
            self.spelling = _spelling(values, self.keys, time)
            typed = {k: values[s] for k, s in self.spelling}
        if self.fused.members and not self.general.roots and not self.samples.terms:
            direct = Direct(
                dict(self.spelling), self.stepped[0], self._again, exact_time, self.kept
            )
            made = self.fused.entry(t, self.pos, self.last_input, self.resume, direct)
            if made is not None:  # this state on, one call: `entry`
                self._start()
                self.entry, self.held = made
                self.stepper = self._handed
                return self.entry(time, values)
        self.stepped = (t, time)
        if self.keeping is not None:
            self.keeping(t, typed)
        return [*self.stepper(t, typed, time)]

    def _keep(self, t: Time, values: dict[FeatureKey, Any]) -> None:
        """A state given to `step`: its terms over samples written in, and kept for
        robustness."""
        if self.samples.terms:
            self.samples.fill(t, values)
        if self.kept is not None:
            self.kept.append(t, values)

    def step_state(
        self, t: Time, values: Mapping[FeatureKey, Any], given: Any = None
    ) -> Sequence[Verdict]:
        """`step` for the stream processor's states, checked already: exact times that
        increase, every feature a value (`given`: the time as the caller wrote it)."""
        given = t if given is None else given
        if not self.general.roots:  # every part fused: this state on, one call (`fast`)
            fast = self.fused.fast(t, self.pos, self.last_input, self.resume)
            if fast is not None:
                self._start()
                self.stepper, self.held = fast
                return self.stepper(t, values, given)
        self.pos += 1
        self.last_input = given
        self._start()
        if self.fused.members:
            self.fused.step(self.pos, t, values, given)
        if self.general.roots:
            self.general.step(self.pos, t, values, given)
        if not self.decided:
            return []
        return self._decided(at_end=False)

    def _start(self) -> None:
        """The formulas added since the last state start at this one."""
        if self.unstarted:
            for m in self.unstarted:
                m.started = True
            self.unstarted = []

    def _handed(
        self, t: Time, values: Mapping[FeatureKey, Any], given: Any = None
    ) -> Sequence[Verdict]:
        """`stepper` while `entry` holds the fast step: back to `step_state`."""
        self._general()
        return self.step_state(t, values, given)

    def resume(self, pos: int, given: Any) -> list[Verdict]:
        """For the fused fast step, at a decision: the position and time it held come back,
        the decided verdicts are reported, and `step_state` runs from the next state on."""
        self.pos, self.last_input = pos, given
        self.stepper, self.held, self.entry = self.step_state, None, self._checked
        self.stepped = (exact_time(given), given)
        return self._decided(at_end=False)

    def _again(self, time: Any, values: Any) -> list[Verdict]:
        """For the fast step's `entry`, a state it does not take: checked, from here on."""
        self._general()
        return self._checked(time, values)

    def advance(self, time: Any) -> list[Verdict]:
        """The stream passed `time` (after the last state) without a state of these formulas:
        the windows that ended by then close.  Returns the verdicts that decides, at `time`;
        the next state must come after it."""
        self._general()
        t = time if type(time) is int else exact_time(time)
        if not t > self.stepped[0]:
            raise DkError(
                f"time {time} is not after the previous state's time {self.stepped[1]} "
                f"(times must increase strictly)"
            )
        self.stepped = (t, time)
        for engine in self.engines:
            engine.advance(t)
        return self._decided(at_end=False, time=time) if self.decided else []

    def deadline(self) -> Time | None:
        """By when a window a formula waits on ends (None: none waits for one)."""
        ends = [end for e in self.engines if (end := e.deadline()) is not None]
        return min(ends, default=None)

    def finish(self, end: Any = None) -> list[Verdict]:
        """End of stream: settle every undecided formula.  `end`: where the data ends, at or
        after the last state (a recording may go on without sampling what these formulas
        read), in the times `step` takes; None: at the last state."""
        self._general()
        cut = None
        if self.end_of_data == "open" and self.last_input is not None:
            last = exact_time(self.last_input)
            cut = last if end is None else max(last, exact_time(end))
        for engine in self.engines:
            engine.finish(cut)
        for m in self.formulas:
            if not m.started and not m.queued:
                m.value, m.queued = None, True
                self.decided.append(m)
        return self._decided(at_end=True)

    def _general(self) -> None:
        """Back to `step_state`, with what the fast step held."""
        if self.held is not None:
            self.pos, self.last_input = self.held()
            if self.pos >= 0:
                self.stepped = (exact_time(self.last_input), self.last_input)
        self.stepper, self.held, self.entry = self.step_state, None, self._checked

    def _decided(self, at_end: bool, time: Any = None) -> list[Verdict]:
        """The decided formulas' verdicts, at the current state (or `time`, advanced to)."""
        time = self.last_input if time is None else time
        out = []
        order = {id(m): n for n, m in enumerate(self.formulas)}
        ready = sorted(self.decided, key=lambda m: order[id(m)])
        self.decided.clear()
        for m in ready:
            if m.value is None and not at_end:  # unknown for good: said at the end
                self.decided.append(m)
                continue
            m.reported = True
            witness = pending = window = None
            unknown: tuple[UnknownSpan, ...] = ()
            if m.value is False and m.why is not None:
                witness = refuted(m.why, time, self.clock)
                window = (min(since(m.why), time), time)
            elif m.value is None:
                unknown = tuple(
                    UnknownSpan(k, s[0], s[1]) for k in m.keys for s in self.unknown.get(k, ())
                )
                pending = None if m.cut is None else m.cut[1].render()
                witness = undecided(unknown, m.started, self.clock, pending)
            margin = None if self.kept is None else self._margin(m, time, at_end)
            out.append(
                Verdict(
                    m.text,
                    m.value,
                    time,
                    at_end,
                    witness,
                    unknown,
                    pending=pending,
                    robustness=margin,
                    window=window,
                )
            )
        return out

    def _margin(self, m: _Formula, time: Any, at_end: bool) -> Margin:
        """A formula's robustness over the states from its first to its verdict's; a window
        reaching past the data then seen (at the end: past its end, with end of data "open")
        unknown in its unseen part."""
        from .robustness import margin

        assert self.kept is not None
        upto = end = None if time is None else exact_time(time)
        if at_end and self.end_of_data != "open":
            end = None
        return margin(self.kept.margin(id(m), upto, end), self.clock)

    def note_unknown(self, keys: Iterable[FeatureKey], pos: int, given: Any) -> None:
        """The engines' `Unknown`: these features were unknown at the state at `pos`."""
        for key in keys:
            spans = self.unknown.setdefault(key, [])
            if spans and spans[-1][2] >= pos - 1:
                spans[-1][1], spans[-1][2] = given, pos
            elif not spans or spans[-1][2] != pos:
                spans.append([given, given, pos])


__all__ = ["ENGINES", "Progressor"]
