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
`end`, the data's end) is unknown in its unseen part.  This is a separate path from Boolean
monitoring: it reads the states a monitor kept for it, once a verdict is decided.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..model import FeatureKey
from ..parse.formula import (
    Atom,
    BoolConst,
    Compare,
    Connective,
    Formula,
    Fresh,
    Not,
    Num,
    Observed,
    Ref,
    Temporal,
    Until,
    feature_key,
    unparse,
)
from .state import evaluate, features, is_text, number, read_key
from .verdict import INF, Margin
from .witness import Clock, Time

Crit = tuple[int, int]  # (atom, position)
Rho = tuple[Any, Any] | None  # (margin, what decided it: a Crit, or None) or None: unknown
Trace = Sequence[tuple[Time, Mapping[FeatureKey, Any]]]


UNKNOWN = Margin(None, None)


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


def _neg(a: Rho) -> Rho:
    return None if a is None else (-a[0], a[1])


_SIGN = {">": 1, ">=": 1, "<": -1, "<=": -1}


def _margin(op: str, a: Any, b: Any) -> Any:
    if op in (">", ">="):
        return a - b
    if op in ("<", "<="):
        return b - a
    return -abs(a - b) if op == "==" else abs(a - b)


class _Evaluation:
    """One formula over one trace: each subformula's margin at every position, once."""

    def __init__(self, trace: Trace, end: Time | None) -> None:
        self.trace, self.end = trace, end
        self.times = [t for t, _ in trace]
        self.atoms: list[Formula] = []
        self.memo: dict[int, list[Rho]] = {}

    def rho(self, f: Formula) -> list[Rho]:
        found = self.memo.get(id(f))
        if found is None:
            found = self.memo[id(f)] = self._rho(f)
        return found

    def _rho(self, f: Formula) -> list[Rho]:
        n = len(self.trace)
        if isinstance(f, Compare) and not is_text(f):
            atom = len(self.atoms)
            self.atoms.append(f)
            out: list[Rho] = []
            if isinstance(f.left, Ref) and isinstance(f.right, Num):  # `X > c`: no interpreter
                k, c, sign = read_key(f.left), f.right.value, _SIGN.get(f.op)
                if sign is not None:
                    for j, (_, values) in enumerate(self.trace):
                        v = values[k]
                        out.append(None if v is None else (sign * (v - c), (atom, j)))
                    return out
            for j, (t, values) in enumerate(self.trace):
                a, b = number(f.left, values, t), number(f.right, values, t)
                out.append(None if a is None or b is None else (_margin(f.op, a, b), (atom, j)))
            return out
        if isinstance(f, Fresh):
            atom = len(self.atoms)
            self.atoms.append(f)
            key = read_key(f)
            return [
                (-INF if values[key] is None else f.limit - values[key], (atom, j))
                for j, (_, values) in enumerate(self.trace)
            ]
        if isinstance(f, BoolConst | Atom | Observed | Compare):
            atom = len(self.atoms)
            self.atoms.append(f)
            out = []
            for j, (t, values) in enumerate(self.trace):
                v = evaluate(f, values, t)
                out.append(None if v is None else (INF if v else -INF, (atom, j)))
            return out
        if isinstance(f, Not):
            return [_neg(r) for r in self.rho(f.arg)]
        if isinstance(f, Connective):
            a, b = self.rho(f.left), self.rho(f.right)
            if f.op == "and":
                return [lower(x, y) for x, y in zip(a, b, strict=True)]
            if f.op == "or":
                return [upper(x, y) for x, y in zip(a, b, strict=True)]
            if f.op == "->":
                return [upper(_neg(x), y) for x, y in zip(a, b, strict=True)]
            return [lower(upper(_neg(x), y), upper(x, _neg(y))) for x, y in zip(a, b, strict=True)]
        if isinstance(f, Temporal):
            return self._temporal(f, self.rho(f.arg), n)
        assert isinstance(f, Until)
        return self._until(f, self.rho(f.left), self.rho(f.right), n)

    def _cut(self, ti: Time, hi: Time | None) -> bool:
        return self.end is not None and hi is not None and ti + hi > self.end

    def _temporal(self, f: Temporal, child: list[Rho], n: int) -> list[Rho]:
        lo, hi, times = f.interval.lo, f.interval.hi, self.times
        out: list[Rho] = []
        if hi is None and f.op in ("always", "eventually", "historically", "once"):
            return self._unbounded(f, child, n)
        if f.op in ("always", "eventually"):
            fold = lower if f.op == "always" else upper
            empty: Rho = (INF if f.op == "always" else -INF, None)
            for i in range(n):
                acc: Rho = empty
                for j in range(i, n):
                    d = times[j] - times[i]
                    if hi is not None and d > hi:
                        break
                    if d >= lo:
                        acc = fold(acc, child[j])
                if self._cut(times[i], hi):
                    acc = fold(acc, None)
                out.append(acc)
            return out
        if f.op in ("historically", "once"):
            fold = lower if f.op == "historically" else upper
            empty = (INF if f.op == "historically" else -INF, None)
            for i in range(n):
                acc = empty
                for j in range(i, -1, -1):
                    d = times[i] - times[j]
                    if hi is not None and d > hi:
                        break
                    if d >= lo:
                        acc = fold(acc, child[j])
                out.append(acc)
            return out
        false: Rho = (-INF, None)
        for i in range(n):
            j = i + 1 if f.op == "next" else i - 1
            if not 0 <= j < n:
                open_ = f.op == "next" and self._cut(times[i], hi)
                out.append(None if open_ else false)
                continue
            gap: Any = abs(times[j] - times[i])
            out.append(child[j] if lo <= gap and (hi is None or gap <= hi) else false)
        return out

    def _unbounded(self, f: Temporal, child: list[Rho], n: int) -> list[Rho]:
        """A window [lo, oo) in linear time: the folds of every suffix (future) or prefix
        (past) of the child's margins, each window one of them (the fold is associative)."""
        future = f.op in ("always", "eventually")
        fold = lower if f.op in ("always", "historically") else upper
        empty: Rho = (INF if fold is lower else -INF, None)
        order = range(n - 1, -1, -1) if future else range(n)
        folds: list[Rho] = [empty] * (n + 1)  # folds[j]: from j to the end (or the start)
        prev = n if future else -1
        for j in order:
            folds[j] = fold(child[j], folds[prev] if 0 <= prev < n else empty)
            prev = j
        lo, times, out = f.interval.lo, self.times, []
        j = 0 if future else -1
        for i in range(n):  # the first state at least lo after i (before i: the last)
            if future:
                j = max(j, i)
                while j < n and times[j] - times[i] < lo:
                    j += 1
                out.append(folds[j] if j < n else empty)
            else:
                while j + 1 <= i and times[i] - times[j + 1] >= lo:
                    j += 1
                out.append(folds[j] if j >= 0 else empty)
        return out

    def _until(self, f: Until, left: list[Rho], right: list[Rho], n: int) -> list[Rho]:
        lo, hi, times = f.interval.lo, f.interval.hi, self.times
        out: list[Rho] = []
        if lo == 0 and hi is None:  # φ U ψ = ψ or (φ and next-state φ U ψ), in linear time
            order = range(n - 1, -1, -1) if f.op == "until" else range(n)
            later: Rho = (-INF, None)
            by: list[Rho] = [None] * n
            for j in order:
                later = by[j] = upper(right[j], lower(left[j], later))
            return by
        for i in range(n):
            acc: Rho = (-INF, None)
            phi: Rho = (INF, None)
            steps = range(i, n) if f.op == "until" else range(i, -1, -1)
            for j in steps:
                d: Any = abs(times[j] - times[i])
                if hi is not None and d > hi:
                    break
                if d >= lo:
                    acc = upper(acc, lower(right[j], phi))
                phi = lower(phi, left[j])
            else:
                if f.op == "until" and self._cut(times[i], hi):
                    acc = upper(acc, lower(None, phi))
            out.append(acc)
        return out


def margins(f: Formula, trace: Trace, end: Time | None = None) -> list[Any]:
    """The margin of `f` at every state of the trace (None: unknown), as rtamt's offline
    evaluator gives them."""
    return [None if r is None else r[0] for r in _Evaluation(trace, end).rho(f)]


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
    run = _Evaluation(trace, end)
    found = run.rho(f)[0]
    if found is None:
        return UNKNOWN
    value, crit = found
    if crit is None:
        return Margin(value, None)
    atom, j = crit
    t, values = trace[j]
    node = run.atoms[atom]
    unit = 1 if clock is None else clock.unit
    start = None if clock is None or clock.origin is None else clock.origin()
    keys = features(node)
    return Margin(
        value,
        unparse(node, unit),
        t if seconds is None else seconds(t),
        None if start is None else (t - start) * unit,
        tuple((str(k), values[k]) for k in keys),
        tuple((str(k), s) for k in keys if (s := (sources or {}).get(_base(k))) is not None),
    )


def _base(k: FeatureKey) -> FeatureKey:
    """The feature a term's key is over (`rate(Yaw[r1])` → Yaw[r1]); a feature's own key."""
    if k.args or not k.name.endswith(")") or "(" not in k.name:
        return k
    return feature_key(k.name[k.name.index("(") + 1 : -1]) or k


__all__ = ["UNKNOWN", "lower", "margins", "robustness", "upper"]
