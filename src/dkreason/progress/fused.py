"""Generated code for the shapes monitors run most, all of a progressor's in one function.

    always S                                   an invariant over a state formula S
    always (A -> eventually[a, b] B)           a response (also `not A or …`, A = true,
                                               and always not always[a, b] S, which is
                                               always eventually[a, b] not S)

A, B and S are temporal-free.  The generated step reads every feature once and evaluates each
distinct state formula once (two-valued fast path, Kleene fallback), so formulas share their
subterms.  Responses that differ only in their window end share one queue of waiting positions
(`Group`): a B at time t settles every waiting position whose window holds t, a window closes at
the state reaching its end, and with members sorted by window end each check is amortised O(1)
however many formulas share the group.  Invariants comparing one feature with a constant
(`always (X > c)`) on the same side share a `Thresholds`: its members sorted so that those a
value breaks are a prefix, so a state costs one comparison however many thresholds there are.
The decisions are those of the general engine (general.py), and so are the witnesses, made
by the same phrases (witness.py): the tests check both against the general engine on random
formulas and traces.  An `Engine` (engine.py); the generated code keeps to this module and
the callables it is given.
"""

from __future__ import annotations

import functools
import operator
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import CodeType
from typing import Any, Protocol, TypeVar

from ..model import FeatureKey
from ..parse.formula import (
    ANY,
    Arith,
    BoolConst,
    Compare,
    Connective,
    Formula,
    Not,
    Num,
    Ref,
    Temporal,
    Unary,
    children,
    oriented,
    unparse,
)
from .compile import exact
from .engine import Append, Entry, Held, Report, Stepper, Timer, Unknown
from .state import GLOBALS, boolean_keys, evaluate, features, is_state, key, python, reads
from .witness import Clock, Time, Why, but, settled, state_was, window_closed, window_cut

TRUE = BoolConst(True)
INF = float("inf")
V = TypeVar("V")


@dataclass(frozen=True, slots=True)
class Shape:
    kind: str  # "invariant" | "response"
    a: Formula  # the invariant, or the response's trigger (TRUE: none)
    b: Formula | None = None
    lo: Time = 0
    hi: Time | None = None
    # for witnesses: the trigger as written (None without `->` or `or`), and the window
    # operator (`eventually[a, b] B`, or the `always[a, b] S` of `not always[a, b] S`)
    trigger: Formula | None = None
    window: Temporal | None = None


def shape(f: Formula) -> Shape | None:
    """The fused shape of a (quantifier-free) formula, if it has one (none for a formula with
    a square root: the generated code here has no path for a value outside its domain)."""
    if not (isinstance(f, Temporal) and f.op == "always" and f.interval == ANY) or _partial(f):
        return None
    body = f.arg
    if is_state(body):
        return Shape("invariant", body)
    trigger: Formula | None = None
    if isinstance(body, Connective) and body.op in ("->", "or") and is_state(body.left):
        a = body.left
        trigger = a if body.op == "->" else a.arg if isinstance(a, Not) else Not(a)
        body = body.right
    target: Formula
    if isinstance(body, Not) and isinstance(body.arg, Temporal) and body.arg.op == "always":
        window, target = body.arg, Not(body.arg.arg)
    elif isinstance(body, Temporal) and body.op == "eventually":
        window, target = body, body.arg
    else:
        return None
    if not is_state(window.arg):
        return None
    lo, hi = exact(window.interval.lo), exact(window.interval.hi)
    assert lo is not None
    return Shape("response", trigger or TRUE, target, lo, hi, trigger, window)


def _partial(f: Any) -> bool:
    todo = [f]
    while todo:
        n = todo.pop()
        if isinstance(n, Unary) and n.op == "sqrt":
            return True
        todo += children(n)
    return False


class Member:
    """One fused part: its shape and where its value goes."""

    def __init__(self, s: Shape, report: Report, clock: Clock) -> None:
        self.shape, self.report, self.clock = s, report, clock
        self.hi: Time | float = INF if s.hi is None else s.hi
        self.unknown = False
        self.done = False
        self.first: Time | None = None  # the time of its first state

    def fail(self, cause: Why) -> None:
        assert self.first is not None
        self.done = True
        # every fused part is an `always`; the verdict names the formula in its place
        self.report(False, settled("always", self.first, False, cause, self.clock))

    def fail_now(self, t: Time, values: dict[FeatureKey, Any]) -> None:
        a = self.shape.a
        text = unparse(a, self.clock.unit)
        self.fail(state_was(text, t, False, features(a), values, self.clock))

    def expire(self, ti: Time) -> None:
        """The window from ti closed: why, as the general engine says it."""
        s, clock = self.shape, self.clock
        assert s.window is not None
        text, child = unparse(s.window, clock.unit), unparse(s.window.arg, clock.unit)
        why = window_closed(text, child, ti, s.lo, s.hi, s.window.op == "always", clock)
        self.fail(why if s.trigger is None else but(unparse(s.trigger, clock.unit), ti, why, clock))

    def cut_off(self, ti: Time, end: Time) -> None:
        """The window from ti reaches past `end`, the end of the data: unknown, and why."""
        s = self.shape
        assert s.window is not None and s.hi is not None
        self.done = True
        text = unparse(s.window, self.clock.unit)
        self.report(None, window_cut(text, ti, s.lo, s.hi, end, self.clock))


class Group:
    """Responses with the same trigger, target and window start: one queue of waiting
    positions [time, weak] (weak: a failure there is unknown, not false), members sorted by
    window end; `unknown_upto` members (a prefix) have seen a weak window close.  `timer` is
    told when the first waiting position's earliest window ends (engine.Timer)."""

    def __init__(self, lo: Time, timer: Timer | None = None) -> None:
        self.lo, self.timer = lo, timer
        self.members: list[Member] = []
        self.pending: deque[list[Any]] = deque()
        self.n_weak = 0
        self.unknown_upto = 0

    def add(self, m: Member) -> None:
        self.members.append(m)
        self.members.sort(key=lambda x: x.hi)
        self.unknown_upto = 0
        for member in self.members:
            if not member.unknown:
                break
            self.unknown_upto += 1

    def _oldest(self, weak: bool) -> Time | None:
        if weak and not self.n_weak:
            return None
        for ti, w in self.pending:
            if w is weak:
                found: Time = ti
                return found
        return None

    def _expire(self, t: Time, closing: bool) -> bool:
        """Members whose window over the oldest strong (weak) position ended before t — or at
        t when `closing` — fail (turn unknown).  Returns whether one failed."""
        members, failed = self.members, False
        strong = self._oldest(False)
        if strong is not None:
            while members and (
                t - strong > members[0].hi or (closing and t - strong == members[0].hi)
            ):
                members.pop(0).expire(strong)
                self.unknown_upto = max(self.unknown_upto - 1, 0)
                failed = True
        weak = self._oldest(True)
        if weak is not None:
            while self.unknown_upto < len(members) and (
                t - weak > members[self.unknown_upto].hi
                or (closing and t - weak == members[self.unknown_upto].hi)
            ):
                members[self.unknown_upto].unknown = True
                self.unknown_upto += 1
        return failed

    def step(self, t: Time, a: bool | None, b: bool | None) -> bool:
        """One state: a and b are the trigger's and target's values.  Returns whether a member
        was decided (false).  Fast path when every value is known; `_general` otherwise."""
        if self.n_weak or a is None or b is None:
            return self._general(t, a, b)
        pending, members, lo = self.pending, self.members, self.lo
        failed = False
        if pending:
            if t - pending[0][0] > members[0].hi:
                failed = self._expire(t, closing=False)
            if b:
                if lo == 0:
                    pending.clear()
                else:
                    while pending and pending[0][0] <= t - lo:
                        pending.popleft()
            if pending and members:
                if t - pending[0][0] >= members[0].hi:
                    failed = self._expire(t, closing=True) or failed
                widest = members[-1].hi if members else -1
                while pending and t - pending[0][0] >= widest:
                    pending.popleft()
        if a and not (b and lo == 0) and members:
            if not pending:
                self._waits(t)
            pending.append([t, False])
            if members[0].hi == 0:
                failed = self._expire(t, closing=True) or failed
                while pending and members and t - pending[0][0] >= members[-1].hi:
                    pending.popleft()
        return failed

    def _general(self, t: Time, a: bool | None, b: bool | None) -> bool:
        pending, lo = self.pending, self.lo
        failed = self._expire(t, closing=False) if pending else False
        if pending and b is not False:
            if b is True:
                while pending and pending[0][0] <= t - lo:
                    self.n_weak -= pending.popleft()[1]
            else:
                for e in pending:
                    if e[0] > t - lo:
                        break
                    if not e[1]:
                        e[1] = True
                        self.n_weak += 1
        if pending:
            failed = self._expire(t, closing=True) or failed
            widest = self.members[-1].hi if self.members else -1
            while pending and t - pending[0][0] >= widest:  # closed for every member
                self.n_weak -= pending.popleft()[1]
        if a is not False and not (lo == 0 and b is True) and self.members:
            if not pending:
                self._waits(t)
            pending.append([t, a is None or (lo == 0 and b is None)])
            self.n_weak += pending[-1][1]
            if self.members[0].hi == 0:
                failed = self._expire(t, closing=True) or failed
                while pending and self.members and t - pending[0][0] >= self.members[-1].hi:
                    self.n_weak -= pending.popleft()[1]
        return failed

    def _waits(self, t: Time) -> None:
        hi = self.members[0].shape.hi
        if self.timer is not None and hi is not None:
            self.timer(t + hi)

    def advance(self, t: Time) -> bool:
        """No state until after t: members whose window over a waiting position ended by
        then fail (turn unknown).  Returns whether one failed."""
        return bool(self.pending) and self._expire(t, closing=True)

    def deadline(self) -> Time | None:
        hi = self.members[0].shape.hi if self.members else None
        return None if not self.pending or hi is None else self.pending[0][0] + hi

    def finish(self, cut: Time | None) -> None:
        """End of stream: for each member, the waiting positions in order until one decides
        it: a window reaching past `cut` (the end of the data) leaves it unknown, a strong one
        closed fails it; a weak one closed makes it unknown (at most).  Without `cut` every
        window closes here."""
        for m in self.members:
            for ti, weak in self.pending:
                if cut is not None and m.hi != INF and ti + m.hi > cut:
                    m.cut_off(ti, cut)
                    break
                if not weak:
                    m.expire(ti)
                    break
                m.unknown = True
        self.members = [m for m in self.members if not m.done]


def threshold(f: Formula) -> tuple[FeatureKey, str, int | float] | None:
    """(feature, op, c) when `f` is `X op c` (or `c op X`) for one feature X and a number c
    (an order: not == or !=)."""
    if not isinstance(f, Compare) or f.op in ("==", "!="):
        return None
    read = oriented(f, Ref)
    c = None if read is None else _constant(read[2])
    return None if read is None or c is None else (key(read[0].feature), read[1], c)


_FOLD: dict[str, Callable[[Any, Any], Any]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
}


def _constant(e: Any) -> int | float | None:
    """The value of a constant expression (`-5`, `200 + 9`) as the generated code computes
    it; None for anything else (division stays with the general path: x / 0)."""
    if isinstance(e, Num):
        return None if isinstance(e.value, bool) else e.value
    if isinstance(e, Unary):
        inner = _constant(e.arg)
        if inner is None or e.op not in ("-", "abs"):
            return None
        return -inner if e.op == "-" else abs(inner)
    if isinstance(e, Arith) and e.op in _FOLD:
        left, right = _constant(e.left), _constant(e.right)
        return None if left is None or right is None else _FOLD[e.op](left, right)
    return None


_BREAKS = {">": ">=", ">=": ">", "<": "<=", "<=": "<"}  # `c BREAKS x`: x breaks `x op c`
_COMPARE = {">=": operator.ge, ">": operator.gt, "<=": operator.le, "<": operator.lt}


class Thresholds:
    """Invariants `always (X op c)` over one feature and op: the members a value x breaks
    are those whose c is on x's side, a prefix when sorted by c."""

    def __init__(
        self,
        op: str,
        members: list[tuple[int | float, Member]],
        on_unknown: Callable[[int, Any], None],
    ) -> None:
        self.on_unknown = on_unknown
        self.broken = _COMPARE[_BREAKS[op]]  # broken(c, x): x breaks `x op c`
        members.sort(key=operator.itemgetter(0), reverse=op in (">", ">="))  # broken first
        self.cs = [c for c, _ in members]
        self.members = [m for _, m in members]
        self.unknown = False

    def step(self, t: Time, x: Any, values: Any, pos: int, given: Any) -> bool:
        if x is None:  # unknown: every member sees an unknown state
            self.on_unknown(pos, given)
            if not self.unknown:
                self.unknown = True
                for m in self.members:
                    m.unknown = True
            return False
        cs, broken, n = self.cs, self.broken, 0
        while n < len(cs) and broken(cs[n], x):
            n += 1
        for m in self.members[:n]:
            m.fail_now(t, values)
        del self.cs[:n], self.members[:n]
        return n > 0


Run = Callable[[Time, Any, int, Any], bool]  # one state (t, values, pos, given): decided?


class Keeper(Protocol):
    """What keeps states for robustness (progress.kept.Kept), as `entry` appends to it."""

    def appenders(self) -> tuple[Append, dict[FeatureKey, Append], int]: ...

    def fold(self) -> int: ...


@dataclass(frozen=True, slots=True)
class Direct:
    """What `entry` needs to take the owner's caller's states as they come: how the caller
    spells each feature, the last state's time, the owner's checked step (for a state `entry`
    does not take: a time not after the last, a feature spelled otherwise), how a time is made
    exact, and with robustness what keeps the states."""

    spelling: Mapping[FeatureKey, Any]
    last: Time | float  # (-inf before the first)
    again: Callable[[Any, Any], Sequence[Any]]
    exact: Callable[[Any], Time]
    keeper: Keeper | None = None


class FusedSet:
    """Every fused part of a progressor, run by one generated step function.  An `Engine`
    (engine.py), and more: while every part a progressor has is fused, `fast` gives its
    whole step for one state, generated."""

    def __init__(self, clock: Clock, unknown: Unknown, timer: Timer | None = None) -> None:
        self.clock, self.unknown, self.timer = clock, unknown, timer
        self.members: list[Member] = []
        self.groups: dict[tuple[Formula, Formula, Time], Group] = {}
        # the generated code for the current members (None: generate it at the next state),
        # and its step, compiled when first needed
        self.code: Code | None = None
        self.run: Run | None = None
        # with robustness: the features a keeper keeps of each state (`entry` appends them);
        # and what the generated `entry` reads (these and the members')
        self.keeps: list[FeatureKey] = []
        self.reads: list[FeatureKey] = []

    def add(self, part: Formula, report: Report) -> bool:
        s = shape(part)
        if s is None:
            return False
        m = Member(s, report, self.clock)
        self.members.append(m)
        if s.kind == "response":
            assert s.b is not None
            self.groups.setdefault((s.a, s.b, s.lo), Group(s.lo, self.timer)).add(m)
        self.changed()
        return True

    def changed(self) -> None:
        """A part came or was decided: the code is generated again at the next state."""
        self.code = self.run = None

    def _generated(self, t: Time) -> Code | None:
        """The code for the members at the state at t (None: none is left)."""
        if self.code is None:
            self.members = [m for m in self.members if not m.done]
            for m in self.members:
                if m.first is None:  # added since the last state: starts now
                    m.first = t
            self.groups = {k: g for k, g in self.groups.items() if g.members}
            self.code = _generate(self) if self.members else None
        return self.code

    def step(self, pos: int, t: Time, values: Mapping[FeatureKey, Any], given: Any) -> None:
        if self.run is None:
            code = self._generated(t)
            self.run = _never if code is None else code.get("step")
        if self.run(t, values, pos, given):
            self.changed()

    def advance(self, t: Time) -> None:
        decided = False
        for g in self.groups.values():
            decided = g.advance(t) or decided
        if decided:
            self.changed()

    def deadline(self) -> Time | None:
        ends = [end for g in self.groups.values() if (end := g.deadline()) is not None]
        return min(ends, default=None)

    def finish(self, cut: Time | None) -> None:
        for g in self.groups.values():
            g.finish(cut)
        for m in self.members:
            if not m.done and m.first is not None:
                m.done = True
                m.report(None if m.unknown else True, None)

    def fast(
        self, t: Time, pos: int, given: Any, resume: Callable[[int, Any], Sequence[V]]
    ) -> tuple[Stepper[V], Held] | None:
        """The owner's whole step for one state, from the state at t on (position `pos`, time
        `given` before it), its position kept inside (`Held` reads it); at a decision it hands
        back to the owner's `resume(pos, given)`, which reports and steps generally from the
        next state on.  None when no part is left."""
        code = self._generated(t)
        if code is None:
            return None
        made: tuple[Stepper[V], Held] = code.get("fast")(pos, given, resume)
        return made

    def entry(
        self,
        t: Time,
        pos: int,
        given: Any,
        resume: Callable[[int, Any], Sequence[V]],
        direct: Direct,
    ) -> tuple[Entry, Held] | None:
        """`fast` for the owner's caller's states as they come (`Direct`), which keeps them for
        robustness itself."""
        code = self._generated(t)
        if code is None:
            return None
        keep = None
        if self.keeps:
            assert direct.keeper is not None
            times, columns, room = direct.keeper.appenders()
            appends = tuple(columns[k] for k in self.reads if k in self.keeps)
            keep = (times, appends, room, direct.keeper.fold)
        spelled = tuple(direct.spelling[k] for k in self.reads)
        made: tuple[Entry, Held] = code.get("entry")(
            pos, given, resume, (spelled, direct.last, direct.again, direct.exact, keep)
        )
        return made

    def note_unknown(self, values: Any, keys: list[FeatureKey], pos: int, given: Any) -> None:
        self.unknown([k for k in keys if values[k] is None], pos, given)


def _never(t: Time, values: Any, pos: int, given: Any) -> bool:
    return False


def _generate(fs: FusedSet) -> Code:
    """The code for the current members, three functions over one scope:

    - `step(t, v, pos, given) -> decided?`, for a progressor that has other parts too;
    - `fast(pos, given, resume)`, which gives the owner's whole step for one state (its
      verdicts returned), called instead while every part it has is fused: one call a state.
      It holds the position and time in its own closure (no attribute stores a state) and
      passes them to what notes an unknown; at a decision it returns `resume(pos, given)`;
      `held` reads them for the owner otherwise;
    - `entry(pos, given, resume, direct)`: the same for the states `Progressor.step` is given
      (`Direct`), as they come: it checks the time, reads each feature by the caller's key
      and keeps what robustness needs, so a state is one call from the caller's loop.

    Values are read into locals first; a rare path (an unknown value, a failure) is given
    them as a dict again."""
    formulas: dict[Formula, str] = {}
    thresholds: dict[tuple[FeatureKey, str], list[tuple[int | float, Member]]] = {}
    for m in fs.members:
        found = threshold(m.shape.a) if m.shape.kind == "invariant" else None
        if found is not None:
            thresholds.setdefault(found[:2], []).append((found[2], m))
    thresholds = {k: ms for k, ms in thresholds.items() if len(ms) > 1}  # one: inline
    shared = {id(m) for ms in thresholds.values() for _, m in ms}
    for m in fs.members:
        for f in (m.shape.a, m.shape.b) if id(m) not in shared else ():
            if f is not None and f != TRUE:
                formulas.setdefault(f, f"e{len(formulas)}")
    keys = list(
        dict.fromkeys([*(k for f in formulas for k in features(f)), *(k for k, _ in thresholds)])
    )
    every = list(dict.fromkeys([*keys, *fs.keeps]))  # what `entry` reads
    fs.reads = every
    scope: dict[str, Any] = {"fs": fs, "slow": evaluate, **GLOBALS}
    names, reading = reads(every, "v", scope)
    reading = reading[: len(keys)]

    def const(value: Any) -> str:  # a global of the generated code: one lookup, no index
        scope[f"c{len(scope)}"] = value
        return f"c{len(scope) - 1}"

    # `vals`: the state's values keyed by feature, where a rare path needs them
    def body(vals: str) -> list[str]:
        lines = []
        by_known: dict[str, list[tuple[Formula, str]]] = {}  # formulas tested alike, once
        for f, var in formulas.items():
            bools = boolean_keys(f)
            known = (
                " and ".join(
                    f"type({names[k]}) is bool" if k in bools else f"{names[k]} is not None"
                    for k in features(f)
                )
                or "True"
            )
            by_known.setdefault(known, []).append((f, var))
        for known, alike in by_known.items():
            lines += [
                f"    if {known}:",
                *(f"        {var} = {python(f, names)}" for f, var in alike),
                "    else:",
            ]
            for f, var in alike:
                lines += [
                    f"        {var} = slow({const(f)}, {vals}, t)",
                    f"        fs.note_unknown({vals}, {const(features(f))}, pos, given)",
                ]
        lines.append("    decided = False")
        for x, (cs, group_step, op) in zip(threshold_reads, groups, strict=True):
            # the first threshold is fixed until one breaks (which regenerates this code): a
            # state that breaks none costs one comparison, not a call
            lines += [
                f"    if {x} is None or {cs} {_BREAKS[op]} {x}:",
                f"        if {group_step}(t, {x}, {vals}, pos, given):",
                "            decided = True",
            ]
        for m in fs.members:
            if m.shape.kind == "invariant" and id(m) not in shared:
                var, me = value(m.shape.a), members[id(m)]
                lines += [
                    f"    if {var} is not True:",
                    f"        if {var} is False:",
                    f"            {me}.fail_now(t, {vals})",
                    "            decided = True",
                    "        else:",
                    f"            {me}.unknown = True",
                ]
        lines += responses
        return lines

    def value(f: Formula) -> str:
        return "True" if f == TRUE else formulas[f]

    threshold_reads, groups = [], []
    for (k, op), ms in thresholds.items():
        group = Thresholds(op, ms, functools.partial(fs.unknown, [k]))
        threshold_reads.append(names[k])
        groups.append((const(group.cs[0]), const(group.step), op))
    members = {id(m): const(m) for m in fs.members}
    responses = []
    for (a, b, lo), group_ in fs.groups.items():
        # with no position waiting, a state changes nothing when the trigger is known false
        # or, for a window from now on, the target holds: no call
        idle = [
            *([f"{value(a)} is False"] if a != TRUE else []),
            *([f"{value(b)} is True"] if lo == 0 else []),
        ]
        guard = f"(not ({' or '.join(idle)}) or {const(group_.pending)}) and " if idle else ""
        responses += [
            f"    if {guard}{const(group_.step)}(t, {value(a)}, {value(b)}):",
            "        decided = True",
        ]
    lines = [*(f"    {line}" for line in reading), *body("v")]
    step = "\n".join(lines)
    fast = "\n".join("    " + line for line in lines)
    # `entry`: the caller's key for each feature (S0, …), read before anything changes (a
    # state without one goes to the owner's checked step, as does a time not after the last)
    spelled = ", ".join(f"S{i}" for i in range(len(every)))
    whole = "{" + ", ".join(f"K{i}: {names[k]}" for i, k in enumerate(every)) + "}"
    keeping = [
        "T(t)",
        *(f"A{i}({names[k]})" for i, k in enumerate(every) if k in fs.keeps),
        "room -= 1",
        "if not room:",
        "    room = fold()",
    ]
    entry = "\n".join(
        [
            "        t = time if type(time) is int else exact(time)",
            "        if not t > last:",
            "            return again(time, v)",
            *(
                ["        try:"]
                + [f"            {names[k]} = v[S{i}]" for i, k in enumerate(every)]
                + ["        except KeyError:", "            return again(time, v)"]
                if every
                else []
            ),
            "        last = t",
            "        pos += 1",
            "        given = time",
            *(f"        {line}" for line in (keeping if fs.keeps else ())),
            *("    " + line for line in body(whole)),
        ]
    )
    appends = ", ".join(f"A{i}" for i, k in enumerate(every) if k in fs.keeps)
    sources = {
        "step": f"def step(t, v, pos, given):\n{step}\n    return decided\n",
        "fast": (
            "def fast(pos, given, resume):\n"
            "    def fast(t, v, g=None):\n"
            "        nonlocal pos, given\n"
            "        pos += 1\n"
            "        given = t if g is None else g\n"
            f"{fast}\n"
            "        if decided:  # generated again at the next state, by the owner's own step\n"
            "            fs.changed()\n"
            "            return resume(pos, given)\n"
            "        return ()\n"
            "    def held():\n"
            "        return pos, given\n"
            "    return fast, held\n"
        ),
        "entry": (
            "def entry(pos, given, resume, direct):\n"
            f"    ({spelled}{',' if every else ''}), last, again, exact, keep = direct\n"
            + (
                f"    T, ({appends}{',' if appends else ''}), room, fold = keep\n"
                if fs.keeps
                else ""
            )
            + "    def entry(time, v):\n"
            "        nonlocal pos, given, last" + (", room\n" if fs.keeps else "\n") + f"{entry}\n"
            "        if decided:\n"
            "            fs.changed()\n"
            "            return resume(pos, given)\n"
            "        return []\n"
            "    def held():\n"
            "        return pos, given\n"
            "    return entry, held\n"
        ),
    }
    return Code(scope, sources)


class Code:
    """The generated code for a fused set's members: one scope (the members, their shared
    checks), each function compiled when first needed (a state of a progressor with other
    parts needs `step`; a progressor's own fast step `fast`, its caller's `entry`)."""

    def __init__(self, scope: dict[str, Any], sources: dict[str, str]) -> None:
        self.scope, self.sources = scope, sources

    def get(self, name: str) -> Any:
        if name not in self.scope:
            source = self.sources[name]
            code = _compiled(source) if len(source) <= CACHED else _compile(source)
            exec(code, self.scope)
        return self.scope[name]


CACHED = 1 << 15  # longer code (hundreds of formulas) is compiled each time: memory stays small


def _compile(source: str) -> CodeType:
    return compile(source, "<fused monitors>", "exec")


_compiled = functools.lru_cache(maxsize=64)(_compile)
"""Generated source compiled once a process: the same formulas' code (a quantified formula's
instances over other objects, a progressor made again) is the same text, its constants and
features bound in each scope."""
