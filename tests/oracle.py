"""A deliberately simple offline evaluator of the MTL semantics (issue 5, item 2), for tests.

Kleene three-valued, point-based, closed intervals, judged at position 0.  At the end of the
trace, a bounded future window reaching past its last state is open (its unseen part unknown)
and an unbounded one closes (finite-trace semantics); `finite=True` closes every window.
`prefix=True` treats the trace as a prefix of an unknown continuation (positions after it
unknown), which is the three-valued prefix evaluation the engine must be at least as early as.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

from dkreason.model import FeatureRef
from dkreason.parse.formula import (
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
)

Trace = list[tuple[Fraction, dict[str, Any]]]


def k_not(a: bool | None) -> bool | None:
    return None if a is None else not a


def k_and(a: bool | None, b: bool | None) -> bool | None:
    if a is False or b is False:
        return False
    return None if a is None or b is None else True


def k_or(a: bool | None, b: bool | None) -> bool | None:
    return k_not(k_and(k_not(a), k_not(b)))


def key(ref: FeatureRef) -> str:
    return ref.name + (f"[{','.join(a.name for a in ref.args)}]" if ref.args else "")


def samples(ref: FeatureRef, tr: Trace, i: int) -> list[tuple[Fraction, Any]]:
    """The feature's samples up to position i, newest first: each state where it has a value."""
    return [(t, v[key(ref)]) for t, v in reversed(tr[: i + 1]) if v[key(ref)] is not None]


def sampled(e: Sampled, tr: Trace, i: int) -> Any:
    found = samples(e.arg.feature, tr, i)
    if e.op == "age":
        return tr[i][0] - found[0][0] if found else None
    if len(found) < 2:
        return None
    (t1, v1), (t0, v0) = found[:2]
    return {"prev": v0, "delta": v1 - v0, "rate": (v1 - v0) / (t1 - t0)}[e.op]


def num(e: Expr, tr: Trace, i: int) -> Any:
    values = tr[i][1]
    if isinstance(e, Num):
        return e.value
    if isinstance(e, Ref):
        return values[key(e.feature)]
    if isinstance(e, Sampled):
        return sampled(e, tr, i)
    if isinstance(e, Func):
        a, b = num(e.left, tr, i), num(e.right, tr, i)
        if a is None or b is None:
            return None
        return {"min": min(a, b), "max": max(a, b), "hypot": math.hypot(a, b)}[e.op]
    if isinstance(e, Unary):
        v = num(e.arg, tr, i)
        if v is None or (e.op == "sqrt" and v < 0):
            return None
        return {"-": -v, "abs": abs(v), "sqrt": math.sqrt(v)}[e.op]
    if isinstance(e, Arith):
        a, b = num(e.left, tr, i), num(e.right, tr, i)
        if a is None or b is None or (e.op == "/" and b == 0):
            return None
        return {"+": a + b, "-": a - b, "*": a * b, "/": a / b}[e.op]
    raise TypeError(e)


def inside(d: Fraction, interval: Interval) -> bool:
    return interval.lo <= d and (interval.hi is None or d <= interval.hi)


def holds(f: Formula, tr: Trace, i: int, prefix: bool = False, finite: bool = False) -> bool | None:
    t = tr[i][0]
    if isinstance(f, BoolConst):
        return f.value
    if isinstance(f, Atom):
        value: bool | None = tr[i][1][key(f.feature)]
        return value
    if isinstance(f, Observed):
        return tr[i][1][key(f.feature)] is not None
    if isinstance(f, Fresh):
        found = samples(f.arg.feature, tr, i)
        return bool(found) and t - found[0][0] <= f.limit
    if isinstance(f, Compare):
        a, b = num(f.left, tr, i), num(f.right, tr, i)
        if a is None or b is None:
            return None
        return bool(
            {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b, "==": a == b, "!=": a != b}[f.op]
        )
    if isinstance(f, Not):
        return k_not(holds(f.arg, tr, i, prefix, finite))
    if isinstance(f, Connective):
        a, b = holds(f.left, tr, i, prefix, finite), holds(f.right, tr, i, prefix, finite)
        return {
            "and": k_and(a, b),
            "or": k_or(a, b),
            "->": k_or(k_not(a), b),
            "<->": None if a is None or b is None else a == b,
        }[f.op]
    assert isinstance(f, Temporal | Until), f
    out: bool | None
    phi: bool | None
    hi = f.interval.hi
    past_the_end = hi is not None and tr[-1][0] < t + hi
    future_open = (prefix and (hi is None or past_the_end)) or (
        not prefix and not finite and past_the_end
    )
    if isinstance(f, Temporal) and f.op in ("eventually", "always"):
        out = f.op == "always"
        for j in range(i, len(tr)):
            if inside(tr[j][0] - t, f.interval):
                v = holds(f.arg, tr, j, prefix, finite)
                out = k_and(out, v) if f.op == "always" else k_or(out, v)
        return (k_and if f.op == "always" else k_or)(out, None) if future_open else out
    if isinstance(f, Temporal) and f.op == "next":
        if i + 1 < len(tr):
            gap = tr[i + 1][0] - t
            return holds(f.arg, tr, i + 1, prefix, finite) if inside(gap, f.interval) else False
        return None if prefix or future_open else False
    if isinstance(f, Temporal) and f.op in ("once", "historically"):
        out = f.op == "historically"
        for j in range(i + 1):
            if inside(t - tr[j][0], f.interval):
                v = holds(f.arg, tr, j, prefix, finite)
                out = k_and(out, v) if f.op == "historically" else k_or(out, v)
        return out
    if isinstance(f, Temporal) and f.op == "previous":
        if i == 0 or not inside(t - tr[i - 1][0], f.interval):
            return False
        return holds(f.arg, tr, i - 1, prefix, finite)
    if isinstance(f, Until) and f.op == "until":
        out = False
        phi = True
        for j in range(i, len(tr)):
            if inside(tr[j][0] - t, f.interval):
                out = k_or(out, k_and(holds(f.right, tr, j, prefix, finite), phi))
            phi = k_and(phi, holds(f.left, tr, j, prefix, finite))
        return k_or(out, k_and(None, phi)) if future_open else out
    if isinstance(f, Until) and f.op == "since":
        out = False
        for j in range(i + 1):
            if inside(t - tr[j][0], f.interval):
                phi = True
                for k in range(j + 1, i + 1):
                    phi = k_and(phi, holds(f.left, tr, k, prefix, finite))
                out = k_or(out, k_and(holds(f.right, tr, j, prefix, finite), phi))
        return out
    raise TypeError(f)
