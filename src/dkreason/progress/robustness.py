"""How much a formula held or failed by: discrete-time STL space robustness over the states
judged, each margin naming its critical atom (the comparison whose value it is) and where
that atom's values came from.

The usual semantics (Donzé and Maler; rtamt's discrete-time offline evaluator): `a > b` and
`a >= b` are a − b, `a < b` and `a <= b` b − a, `a == b` −|a − b|, `a != b` |a − b|; `and`,
`always` and `historically` take the minimum, `or`, `eventually` and `once` the maximum,
windows over the states inside them, `not` negates, `a -> b` is `not a or b`; `until` and
`since` the max-min of their definition.  A condition (`P[x]`, `observed(X)`, a string
comparison, `true`) is ±∞; `fresh(X, d)` is d − age(X).  An empty window is +∞ for `always`
and −∞ for `eventually`, as rtamt's.

Unknown values give no margin: an unknown part of a minimum leaves it unknown unless a known
part is negative (the formula fails whatever it is), and dually for a maximum, so a margin's
sign is always its Boolean verdict's, and a window that the end of the data cuts off (with
`end`, the data's end) is unknown in its unseen part.

Each subformula's margins at every state are one numpy array (NaN: unknown), windows folded
by a sparse table of minima over the window bounds `searchsorted` finds, so a state costs a
few array operations, not Python steps.  The arrays are floats: the reported margin is taken
again, exactly, from its critical atom, found by walking back from the root to the child
whose value it is (the first such, left to right and earliest in time, as the folds keep
ties).  kept.py decides which states a monitor keeps for this.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from ..model import FeatureKey
from ..parse.formula import (
    Arith,
    Atom,
    BoolConst,
    Compare,
    Connective,
    Expr,
    Formula,
    Fresh,
    Func,
    Interval,
    Not,
    Num,
    Observed,
    Ref,
    Sampled,
    Temporal,
    Unary,
    Until,
    feature_key,
    unparse,
)
from .state import evaluate, features, is_text, number, read_key
from .verdict import INF, Margin
from .witness import Clock, Time

Rho = tuple[Any, Any] | None  # (margin, what decided it) or None: unknown
Trace = Sequence[tuple[Time, Mapping[FeatureKey, Any]]]
Array = NDArray[np.float64]
Index = NDArray[np.intp]
Crit = tuple[Formula, int, int]  # (atom, position, sign: the root's margin is sign × the atom's)

UNKNOWN = Margin(None, None)
# A comparison that fails by nothing (`a < b` with a = b, `a != b` with a = b) is 0 and fails:
# in the arrays, minus the smallest positive float, so that a minimum takes it as a failure
# (the formula fails whatever an unknown part is) and `not` makes it hold; said as 0.
_NOTHING = float(np.nextafter(0.0, 1.0))
_STRICT = ("<", ">", "!=")
_FUTURE = ("always", "eventually")
_LOW = ("always", "historically")  # folds taking the minimum


def lower(a: Rho, b: Rho) -> Rho:
    """Minimum (and): unknown unless a known part fails."""
    if a is None:
        return b if b is not None and b[0] < 0 else None
    if b is None:
        return a if a[0] < 0 else None
    return a if a[0] <= b[0] else b


def upper(a: Rho, b: Rho) -> Rho:
    """Maximum (or): unknown unless a known part holds."""
    if a is None:
        return b if b is not None and b[0] > 0 else None
    if b is None:
        return a if a[0] > 0 else None
    return a if a[0] >= b[0] else b


def low(a: Any, b: Any) -> Array:
    """`lower` of margin arrays (NaN: unknown)."""
    m = np.fmin(a, b)
    out: Array = np.where(m < 0, m, np.minimum(a, b))
    return out


def high(a: Any, b: Any) -> Array:
    """`upper` of margin arrays (NaN: unknown)."""
    m = np.fmax(a, b)
    out: Array = np.where(m > 0, m, np.maximum(a, b))
    return out


def _low1(a: float, b: float) -> float:
    return float(low(a, b))


def _high1(a: float, b: float) -> float:
    return float(high(a, b))


def window_min(x: Array, first: Index, stop: Index) -> Array:
    """Each position's `lower` fold of x over [first, stop) (+∞ when empty): a suffix or
    prefix minimum when every window reaches an end, else a sparse table of minima, one level
    per power of two up to the longest window, each query two lookups."""
    unknown = np.isnan(x)
    some = bool(unknown.any())
    known = np.where(unknown, np.inf, x) if some else x
    n = len(x)
    out = np.full(len(first), np.inf)
    length = stop - first
    if n and len(first):
        if (stop == n).all():
            ends = np.append(np.minimum.accumulate(known[::-1])[::-1], np.inf)
            out = np.where(length > 0, ends[np.minimum(first, n)], np.inf)
        elif (first == 0).all():
            ends = np.insert(np.minimum.accumulate(known), 0, np.inf)
            out = ends[stop]
        else:
            level, span, top = known, 1, int(length.max())
            while span <= top:
                pick = (length >= span) & (length < 2 * span)
                if pick.any():
                    out[pick] = np.minimum(level[first[pick]], level[stop[pick] - span])
                level = np.minimum(level[:-span], level[span:])
                span *= 2
    if not some:
        return out
    counts = np.concatenate(([0], np.cumsum(unknown)))
    some_unknown = counts[stop] > counts[np.minimum(first, stop)]
    return np.where((out < 0) | ~some_unknown, out, np.nan)


def _window(x: Array, first: Index, stop: Index, minimum: bool) -> Array:
    return window_min(x, first, stop) if minimum else -window_min(-x, first, stop)


def _sign(op: str) -> int:
    return 1 if op in (">", ">=") else -1


def _margin(op: str, a: Any, b: Any) -> Any:
    if op in (">", ">=", "<", "<="):
        return _sign(op) * (a - b)
    return -abs(a - b) if op == "==" else abs(a - b)


@dataclass(frozen=True, slots=True)
class Critical:
    """What a margin is: its exact `value`, the atom whose margin it is, at `time`, which read
    `values` there."""

    value: Any
    atom: Formula
    time: Time
    values: tuple[tuple[FeatureKey, Any], ...]


class Columns(Sequence[tuple[Time, Mapping[FeatureKey, Any]]]):
    """A trace held as columns, as kept.py keeps states: its times, and each feature's values in
    a list of their own (a state costs an append per feature, a column reads in one call); a
    state is made again as (time, values) only where an atom needs one."""

    __slots__ = ("times", "columns")

    def __init__(self, times: list[Time], columns: dict[FeatureKey, list[Any]]) -> None:
        self.times, self.columns = times, columns

    def __len__(self) -> int:
        return len(self.times)

    @overload
    def __getitem__(self, j: int) -> tuple[Time, Mapping[FeatureKey, Any]]: ...

    @overload
    def __getitem__(self, j: slice) -> Columns: ...

    def __getitem__(self, j: int | slice) -> Any:
        if isinstance(j, slice):
            return Columns(self.times[j], {k: c[j] for k, c in self.columns.items()})
        return self.times[j], {k: c[j] for k, c in self.columns.items()}

    def __iter__(self) -> Iterator[tuple[Time, Mapping[FeatureKey, Any]]]:
        keys = list(self.columns)
        for t, *values in zip(self.times, *self.columns.values(), strict=True):
            yield t, dict(zip(keys, values, strict=True))


class Signals:
    """One trace's margins: each subformula's at every state, computed once; `end`: where the
    data ends (None: every window closes at the last state)."""

    def __init__(self, trace: Trace, end: Time | None = None) -> None:
        self.trace, self.end, self.n = trace, end, len(trace)
        self._times: NDArray[Any] | None = None
        self.memo: dict[int, Array] = {}
        self.columns: dict[FeatureKey, Array] = {}
        self.windows: dict[tuple[Interval, bool], tuple[Index, Index]] = {}

    @property
    def times(self) -> NDArray[Any]:
        """The states' times (read when a window needs them)."""
        if self._times is None:
            trace = self.trace
            times = trace.times if isinstance(trace, Columns) else [t for t, _ in trace]
            self._times = np.array(times)
            if self._times.dtype.kind != "i":  # exact: Fractions, or integers past int64
                self._times = np.array(times, dtype=object)
        return self._times

    def rho(self, f: Formula) -> Array:
        found = self.memo.get(id(f))
        if found is None:
            with np.errstate(all="ignore"):
                found = self.memo[id(f)] = self._rho(f)
        return found

    # ---- margins at every state ----------------------------------------------------------

    def column(self, e: Ref | Sampled | Fresh) -> Array:
        """A feature's (or term's) values at every state, NaN where it has none."""
        k = read_key(e)
        found = self.columns.get(k)
        if found is None:
            trace = self.trace
            try:
                raw = trace.columns[k] if isinstance(trace, Columns) else [v[k] for _, v in trace]
                found = np.fromiter(raw, float, len(raw))  # (None: NaN)
            except (TypeError, ValueError):  # not numbers: said as the Boolean path says it
                assert not isinstance(e, Fresh)
                found = np.array(
                    [math.nan if (x := number(e, v, t)) is None else x for t, v in self.trace],
                    dtype=float,
                )
            self.columns[k] = found
        return found

    def term(self, e: Expr) -> Any:
        if isinstance(e, Num):
            return float(e.value)
        if isinstance(e, Ref | Sampled):
            return self.column(e)
        if isinstance(e, Arith):
            a, b = self.term(e.left), self.term(e.right)
            if e.op == "/":
                return np.where(np.equal(b, 0), np.nan, np.divide(a, b))
            return a + b if e.op == "+" else a - b if e.op == "-" else a * b
        if isinstance(e, Unary):
            a = self.term(e.arg)
            if e.op == "sqrt":
                return np.where(np.less(a, 0), np.nan, np.sqrt(a))
            return np.negative(a) if e.op == "-" else np.abs(a)
        assert isinstance(e, Func)
        a, b = self.term(e.left), self.term(e.right)
        return {"min": np.minimum, "max": np.maximum, "hypot": np.hypot}[e.op](a, b)

    def _rho(self, f: Formula) -> Array:
        n = self.n
        if isinstance(f, Compare) and not is_text(f):
            a, b = self.term(f.left), self.term(f.right)
            out = np.asarray(_margin(f.op, a, b), dtype=float)
            if f.op in _STRICT:
                out = np.where(out == 0, -_NOTHING, out)
            return np.broadcast_to(out, (n,))
        if isinstance(f, Fresh):
            age = self.column(f)
            return np.where(np.isnan(age), -np.inf, float(f.limit) - age)
        if isinstance(f, BoolConst | Atom | Observed | Compare):
            return np.array(
                [
                    math.nan if (v := evaluate(f, values, t)) is None else INF if v else -INF
                    for t, values in self.trace
                ],
                dtype=float,
            )
        if isinstance(f, Not):
            return -self.rho(f.arg)
        if isinstance(f, Connective):
            a, b = self.rho(f.left), self.rho(f.right)
            if f.op == "and":
                return low(a, b)
            if f.op == "or":
                return high(a, b)
            if f.op == "->":
                return high(-a, b)
            return low(high(-a, b), high(a, -b))
        if isinstance(f, Temporal):
            return self._temporal(f, self.rho(f.arg))
        assert isinstance(f, Until)
        return self._until(f, self.rho(f.left), self.rho(f.right))

    def bounds(self, interval: Interval, future: bool) -> tuple[Index, Index]:
        """Each state's window [first, stop) of positions: those at least `lo` and at most `hi`
        after it (`future`) or before it (found once a window: a critical atom looks again)."""
        found = self.windows.get((interval, future))
        if found is None:
            found = self.windows[(interval, future)] = self._bounds(interval, future)
        return found

    def _bounds(self, interval: Interval, future: bool) -> tuple[Index, Index]:
        n = self.n
        idx = np.arange(n, dtype=np.intp)
        if interval.lo == 0 and interval.hi is None:  # from each state to the end (or start)
            return (idx, np.full(n, n, np.intp)) if future else (np.zeros(n, np.intp), idx + 1)
        times = self.times
        lo, hi = self.integral(interval)
        # (times increase strictly: a window from the state itself starts, or ends, there)
        if future:
            first = idx if lo == 0 else np.searchsorted(times, times + lo, "left")
            stop = np.full(n, n) if hi is None else np.searchsorted(times, times + hi, "right")
        else:
            first = np.zeros(n, np.intp) if hi is None else np.searchsorted(times, times - hi)
            stop = idx + 1 if lo == 0 else np.searchsorted(times, times - lo, "right")
        return first.astype(np.intp), stop.astype(np.intp)

    def integral(self, interval: Interval) -> tuple[Any, Any]:
        """A window's bounds as integer times admit them (exact: `d >= 2.5` is `d >= 3`)."""
        lo, hi = interval.lo, interval.hi
        if self.times.dtype.kind == "i":
            return math.ceil(lo), None if hi is None else math.floor(hi)
        return lo, hi

    def cut(self, hi: Any) -> NDArray[np.bool_] | None:
        """The states whose window of length `hi` reaches past the end of the data."""
        if self.end is None or hi is None:
            return None
        if self.times.dtype.kind == "i" and type(self.end) is int:
            hi = math.ceil(hi)  # t + hi > end, in integers
        return np.asarray(self.times + hi > self.end, dtype=bool)

    def _temporal(self, f: Temporal, child: Array) -> Array:
        hi = f.interval.hi
        if f.op in ("next", "previous"):
            ok, j = self._step(f)
            out = np.where(ok, child[j], -np.inf)
            cut = self.cut(hi) if f.op == "next" else None
            if cut is not None and self.n:
                out[-1] = np.nan if cut[-1] else out[-1]
            return out
        first, stop = self.bounds(f.interval, f.op in _FUTURE)
        out = _window(child, first, stop, f.op in _LOW)
        cut = self.cut(hi) if f.op in _FUTURE else None
        if cut is not None:
            out = np.where(cut, low(out, np.nan) if f.op == "always" else high(out, np.nan), out)
        return out

    def _step(self, f: Temporal) -> tuple[NDArray[np.bool_], Index]:
        """`next`/`previous`: whether each state's neighbour is inside the window, and which."""
        n, times = self.n, self.times
        j = np.arange(n) + (1 if f.op == "next" else -1)
        valid = (j >= 0) & (j < n)
        j = np.clip(j, 0, max(n - 1, 0))
        gap = np.abs(times[j] - times) if n else times
        lo, hi = self.integral(f.interval)
        ok = valid & np.asarray(gap >= lo, dtype=bool)
        if hi is not None:
            ok &= np.asarray(gap <= hi, dtype=bool)
        return ok, j

    def _until(self, f: Until, left: Array, right: Array) -> Array:
        n, future = self.n, f.op == "until"
        if f.interval.lo == 0 and f.interval.hi is None:  # φ U ψ = ψ or (φ and next φ U ψ)
            order = range(n - 1, -1, -1) if future else range(n)
            a, b, out, later = left.tolist(), right.tolist(), np.empty(n), -INF
            for j in order:
                later = out[j] = _high1(b[j], _low1(a[j], later))
            return out
        first, stop = self.bounds(f.interval, future)
        idx = np.arange(n, dtype=np.intp)
        reach = stop - idx if future else idx - first + 1  # the steps from i in the window
        acc, phi = np.full(n, -np.inf), np.full(n, np.inf)
        for m in range(int(reach.max(initial=0))):
            js = idx + m if future else idx - m
            live = m < reach
            at = np.clip(js, 0, n - 1)
            inside = live & ((js >= first) if future else (js < stop))
            acc = np.where(inside, high(acc, low(right[at], phi)), acc)
            phi = np.where(live, low(phi, left[at]), phi)
        cut = self.cut(f.interval.hi) if future else None
        if cut is not None:
            acc = np.where(cut, high(acc, low(np.nan, phi)), acc)
        return acc

    # ---- where a margin comes from -------------------------------------------------------

    def critical(self, f: Formula, i: int) -> Crit | None:
        """The atom (and state) whose margin is `f`'s at position i, and the sign relating
        them; None when an empty window's ±∞ (or a false `next`) decided it."""
        sign = 1
        while True:
            w = self.rho(f)[i]
            if isinstance(f, Not):
                f, sign = f.arg, -sign
                continue
            if isinstance(f, Connective):
                pairs = {
                    "and": ((f.left, 1), (f.right, 1)),
                    "or": ((f.left, 1), (f.right, 1)),
                    # on a tie the consequent: what was owed, not the trigger that held
                    "->": ((f.right, 1), (f.left, -1)),
                }.get(f.op, ((f.left, -1), (f.right, 1), (f.left, 1), (f.right, -1)))
                g, s = next((g, s) for g, s in pairs if s * self.rho(g)[i] == w)
                f, sign = g, sign * s
                continue
            if isinstance(f, Temporal):
                found = self._in_window(f, i, w)
                if found is None:
                    return None
                f, i = f.arg, found
                continue
            if isinstance(f, Until):
                at = self._in_until(f, i, w)
                if at is None:
                    return None
                f, i = at
                continue
            return f, i, sign

    def _in_window(self, f: Temporal, i: int, w: float) -> int | None:
        child = self.rho(f.arg)
        if f.op in ("next", "previous"):
            ok, j = self._step(f)
            return int(j[i]) if ok[i] and child[j[i]] == w else None
        if f.interval.hi is not None and w == (INF if f.op in _LOW else -INF):
            return None  # the empty window's value, as the fold starts from it
        first, stop = self.bounds(f.interval, f.op in _FUTURE)
        hits = np.flatnonzero(child[first[i] : stop[i]] == w)
        if not len(hits):
            return None
        return int(first[i] + (hits[0] if f.op in _FUTURE else hits[-1]))

    def _in_until(self, f: Until, i: int, w: float) -> tuple[Formula, int] | None:
        """The first position of the until's window whose `right and left-so-far` is w, and of
        that the right side, else the left's first equal to w (ties keep the earlier)."""
        if w == -INF:
            return None
        left, right = self.rho(f.left), self.rho(f.right)
        future = f.op == "until"
        if f.interval.lo == 0 and f.interval.hi is None:  # as the recurrence keeps ties
            for j in range(i, self.n) if future else range(i, -1, -1):
                if right[j] == w:
                    return f.right, j
                if left[j] == w:
                    return f.left, j
            return None
        first, stop = self.bounds(f.interval, future)
        steps = range(i, self.n) if future else range(i, -1, -1)
        seen: list[int] = []
        phi = INF
        for j in steps:
            if future and j >= stop[i] or not future and j < first[i]:
                break
            inside = j >= first[i] if future else j < stop[i]
            if inside and _low1(right[j], phi) == w:
                if right[j] == w:
                    return f.right, j
                break
            phi = _low1(phi, left[j])
            seen.append(j)
        else:
            seen = list(steps)  # a window the end of the data cut: its left side
        return next(((f.left, k) for k in seen if left[k] == w), None)

    def found(self, crit: Crit) -> Critical:
        """The critical atom's margin, exactly, with the values it read."""
        atom, j, sign = crit
        t, values = self.trace[j]
        value: Any
        if isinstance(atom, Compare) and not is_text(atom):
            a, b = number(atom.left, values, t), number(atom.right, values, t)
            value = self.rho(atom)[j] if a is None or b is None else _margin(atom.op, a, b)
            if value == 0:  # held or failed by nothing: a signed zero says which
                value = -0.0 if atom.op in _STRICT else 0.0
        elif isinstance(atom, Fresh):
            age = values[read_key(atom)]
            value = -INF if age is None else atom.limit - age
        else:
            value = INF if evaluate(atom, values, t) else -INF
        return Critical(sign * value, atom, t, tuple((k, values[k]) for k in features(atom)))


def margins(f: Formula, trace: Trace | Signals, end: Time | None = None) -> list[Any]:
    """The margin of `f` at every state of the trace (None: unknown), as rtamt's offline
    evaluator gives them (floats); formulas over one trace share its `Signals`."""
    rho = (trace if isinstance(trace, Signals) else Signals(trace, end)).rho(f)
    rho = np.where(np.abs(rho) == _NOTHING, 0.0, rho)  # said as 0, as rtamt's
    out: list[Any] = rho.tolist()
    return [None if math.isnan(r) else r for r in out] if np.isnan(rho).any() else out


def at_start(f: Formula, trace: Trace | Signals, end: Time | None = None) -> Rho:
    """`f`'s margin at the trace's first state: (float, its Critical or None), None unknown
    (formulas over one trace share its `Signals`)."""
    run = trace if isinstance(trace, Signals) else Signals(trace, end)
    w = float(run.rho(f)[0])
    if math.isnan(w):
        return None
    crit = run.critical(f, 0)
    return w, None if crit is None else run.found(crit)


def margin(
    found: Rho,
    clock: Clock | None = None,
    sources: Mapping[FeatureKey, str] | None = None,
    seconds: Callable[[Any], Any] | None = None,
) -> Margin:
    """A margin as a verdict says it (`at_start`'s, or kept.py's)."""
    if found is None:
        return UNKNOWN
    value, crit = found
    if crit is None:
        return Margin(value, None)
    assert isinstance(crit, Critical)
    t = crit.time
    unit = 1 if clock is None else clock.unit
    start = None if clock is None or clock.origin is None else clock.origin()
    return Margin(
        crit.value,
        unparse(crit.atom, unit),
        t if seconds is None else seconds(t),
        None if start is None else (t - start) * unit,
        tuple((str(k), v) for k, v in crit.values),
        tuple(
            (str(k), s) for k, _ in crit.values if (s := (sources or {}).get(_base(k))) is not None
        ),
    )


def robustness(
    f: Formula,
    trace: Trace,
    end: Time | None = None,
    clock: Clock | None = None,
    sources: Mapping[FeatureKey, str] | None = None,
    seconds: Callable[[Any], Any] | None = None,
) -> Margin:
    """The margin of `f` (quantifier-free, bounds in the trace's units) at the trace's first
    state (value None when unknown values leave it undecided).  `end`: where the data ends (a
    window reaching past it is unknown in its unseen part); None: every window closes at the
    last state (the finite-trace semantics, rtamt's).  `clock` says the critical atom's time
    as `t+…` from the run's start; `seconds` turns a trace time into what a verdict's `time`
    says; `sources` names each feature's source."""
    if not trace:
        return UNKNOWN
    return margin(at_start(f, trace, end), clock, sources, seconds)


def _base(k: FeatureKey) -> FeatureKey:
    """The feature a term's key is over (`rate(Yaw[r1])` → Yaw[r1]); a feature's own key."""
    if k.args or not k.name.endswith(")") or "(" not in k.name:
        return k
    return feature_key(k.name[k.name.index("(") + 1 : -1]) or k


__all__ = [
    "UNKNOWN",
    "Columns",
    "Critical",
    "Signals",
    "at_start",
    "lower",
    "margin",
    "margins",
    "robustness",
    "upper",
]
