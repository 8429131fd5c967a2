"""Temporal-free subformulas ("state formulas") compiled to Python once.

Each compiles to a function of the state's values returning True, False or None (unknown,
Kleene).  The generated code reads every feature first, then takes a two-valued fast path
when all it reads as values are known (`observed(X)` and `fresh(X, d)` read only whether X
has one, and how old), and falls back to a three-valued interpreter otherwise.  A term over a
feature's samples (`rate(X)`) is read from the state as a feature is (stream.terms).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Iterable, Mapping
from fractions import Fraction
from typing import Any

from ..errors import DkError
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
    Not,
    Num,
    Observed,
    Ref,
    Sampled,
    Str,
    Unary,
    age_bound,
    children,
    unparse,
)
from ..stream.terms import term_key
from ..stream.units import NS

Value = bool | None
StateFn = Callable[[Mapping[FeatureKey, Any], Any], Value]  # (values, time)

_CMP = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "==": operator.eq,
    "!=": operator.ne,
}
_ARITH = {"+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv}


def key(feature: Any) -> FeatureKey:
    """The state key of a (ground) feature reference."""
    return FeatureKey(feature.name, tuple(a.name for a in feature.args))


def read_key(n: Atom | Ref | Observed | Sampled | Fresh) -> FeatureKey:
    """The state key a leaf reads: its feature's, or its term's (`fresh` reads the age)."""
    if isinstance(n, Sampled):
        return term_key(n.op, key(n.arg.feature))
    if isinstance(n, Fresh):
        return term_key("age", key(n.arg.feature))
    return key(n.feature)


LEAVES = (Atom, Ref, Observed, Sampled, Fresh)


def terms(f: Any) -> set[tuple[str, FeatureKey]]:
    """The terms over samples a formula reads, as (term, feature): what its states carry."""
    out: set[tuple[str, FeatureKey]] = set()
    todo = [f]
    while todo:
        n = todo.pop()
        if isinstance(n, Sampled):
            out.add((n.op, key(n.arg.feature)))
        elif isinstance(n, Fresh):
            out.add(("age", key(n.arg.feature)))
        else:
            todo += children(n)
    return out


def fresh_limits(f: Any) -> set[tuple[FeatureKey, Fraction]]:
    """Each age a formula's truth turns at, as (X, d): the instant X's last sample grows older
    than d is a deadline, at which whoever makes the states makes one.  `fresh(X, d)` turns
    past d; `age(X) <= c` and `> c` past c, `< c` and `>= c` at c (past c less 1 ns), `==`
    and `!=` at both."""
    out: set[tuple[FeatureKey, Fraction]] = set()
    todo = [f]
    while todo:
        n = todo.pop()
        if isinstance(n, Fresh):
            out.add((key(n.arg.feature), n.limit))
            continue
        if isinstance(n, Compare):
            out |= _age_limits(n)
        todo += children(n)
    return out


_BEFORE = Fraction(1, NS)  # an age turns at c: past c less 1 ns


def _age_limits(c: Compare) -> set[tuple[FeatureKey, Fraction]]:
    """The ages `age(X) op d` (either way round) turns at."""
    found = age_bound(c)
    if found is None:
        return set()
    age, op, limit = found
    turns = {"<=": (limit,), ">": (limit,), "<": (limit - _BEFORE,)}
    turns[">="] = turns["<"]
    return {(key(age.arg.feature), t) for t in turns.get(op, (limit, limit - _BEFORE)) if t >= 0}


def base_features(f: Any) -> list[FeatureKey]:
    """The features a formula reads, its terms' features in place of the terms."""
    out: dict[FeatureKey, None] = {}
    todo = [f]
    while todo:
        n = todo.pop()
        if isinstance(n, Atom | Ref | Observed):
            out[key(n.feature)] = None
        todo += reversed(children(n))
    return list(out)


def is_state(f: Formula) -> bool:
    if isinstance(f, BoolConst | Atom | Observed | Fresh | Compare):
        return True
    if isinstance(f, Not):
        return is_state(f.arg)
    if isinstance(f, Connective):
        return is_state(f.left) and is_state(f.right)
    return False


def features(node: Any) -> list[FeatureKey]:
    """Feature keys a state formula or expression reads, in order of appearance."""
    out: dict[FeatureKey, None] = {}

    def walk(n: Any) -> None:
        if isinstance(n, LEAVES):
            out[read_key(n)] = None
            return
        for child in children(n):
            walk(child)

    walk(node)
    return list(out)


def valued(node: Any) -> list[FeatureKey]:
    """The features a state formula reads the values of (not only whether they have one)."""
    if isinstance(node, Observed | Fresh):
        return []
    if isinstance(node, Atom | Ref | Sampled):
        return [read_key(node)]
    return list(dict.fromkeys(k for child in children(node) for k in valued(child)))


def uses(f: Any) -> dict[FeatureKey, str]:
    """How a formula uses each feature: as a condition (bool), a number or a string."""
    out: dict[FeatureKey, str] = {}

    def walk(n: Any, as_: str) -> None:
        if isinstance(n, Atom):
            out.setdefault(key(n.feature), "bool")
        elif isinstance(n, Ref):
            out.setdefault(key(n.feature), as_)
        elif isinstance(n, Fresh) or isinstance(n, Sampled) and n.op == "age":
            pass  # how old X's sample is, whatever X holds
        elif isinstance(n, Sampled):
            walk(n.arg, as_ if n.op == "prev" else "number")
        elif isinstance(n, Compare):
            if is_text(n) and n.op not in ("==", "!="):
                raise DkError(f"strings compare only with == or !=, not {n.op}: {unparse(n)}")
            for side in (n.left, n.right):
                walk(side, "string" if is_text(n) else "number")
        else:
            for child in children(n):
                walk(child, as_)

    walk(f, "number")
    return out


USE = {"bool": "a condition (boolean)", "number": "a number", "string": "a string"}


def feature_uses(formulas: Iterable[tuple[str, Any]]) -> dict[FeatureKey, tuple[str, str]]:
    """How a set of formulas (text, tree) uses each feature, and the first formula that does;
    a feature used two ways is an error."""
    out: dict[FeatureKey, tuple[str, str]] = {}
    for text, tree in formulas:
        for k, use in uses(tree).items():
            first = out.setdefault(k, (use, text))
            if first[0] != use:
                raise DkError(f"{k} is used as {USE[first[0]]} and as {USE[use]}")
    return out


# ---- three-valued interpreter (the slow path, and the reference for the fast one) ----------


def evaluate(f: Formula, values: Mapping[FeatureKey, Any], time: object = None) -> Value:
    if isinstance(f, BoolConst):
        return f.value
    if isinstance(f, Observed):
        return values[key(f.feature)] is not None
    if isinstance(f, Fresh):
        age = values[read_key(f)]
        return age is not None and age <= f.limit
    if isinstance(f, Atom):
        v = values[key(f.feature)]
        if v is None or isinstance(v, bool):
            return v
        raise DkError(
            f"feature {key(f.feature)} is used as a condition but has the value "
            f"{v!r} at time {time}"
        )
    if isinstance(f, Compare):
        if is_text(f):
            left, right = _text(f.left, values, time), _text(f.right, values, time)
        else:
            left, right = number(f.left, values, time), number(f.right, values, time)
        return None if left is None or right is None else bool(_CMP[f.op](left, right))
    if isinstance(f, Not):
        v = evaluate(f.arg, values, time)
        return None if v is None else not v
    if isinstance(f, Connective):
        a, b = evaluate(f.left, values, time), evaluate(f.right, values, time)
        return kleene(f.op, a, b)
    raise TypeError(type(f).__name__)


def kleene(op: str, a: Value, b: Value) -> Value:
    if op == "and":
        return False if a is False or b is False else None if a is None or b is None else True
    if op == "or":
        return True if a is True or b is True else None if a is None or b is None else False
    if op == "->":
        return kleene("or", None if a is None else not a, b)
    if op == "<->":
        return None if a is None or b is None else a == b
    raise ValueError(op)


def is_text(f: Compare) -> bool:
    """A comparison of strings: one side is a quoted constant."""
    return isinstance(f.left, Str) or isinstance(f.right, Str)


def _text(e: Expr, values: Mapping[FeatureKey, Any], time: object) -> str | None:
    if isinstance(e, Str):
        return e.value
    if isinstance(e, Ref) or isinstance(e, Sampled) and e.op == "prev":
        v = values[read_key(e)]
        if v is not None and not isinstance(v, str):
            raise DkError(
                f"feature {read_key(e)} is compared with a string but has the "
                f"value {v!r} at time {time}"
            )
        return v
    raise DkError(f"only a feature compares with a string, not {unparse(e)}")


def number(e: Expr, values: Mapping[FeatureKey, Any], time: object) -> Any:
    if isinstance(e, Num):
        return e.value
    if isinstance(e, Str):
        raise DkError(f"the string {unparse(e)} is used as a number")
    if isinstance(e, Ref):
        v = values[key(e.feature)]
        if v is not None and not isinstance(v, int | float) and not hasattr(v, "__truediv__"):
            raise DkError(
                f"feature {key(e.feature)} is compared as a number but has the "
                f"value {v!r} at time {time}"
            )
        return v
    if isinstance(e, Sampled):
        return values[read_key(e)]
    if isinstance(e, Unary):
        v = number(e.arg, values, time)
        if v is None or e.op == "sqrt" and v < 0:
            return None  # out of its domain: unknown, never a violation
        return -v if e.op == "-" else FUNCTIONS[e.op](v)
    if isinstance(e, Func):
        a, b = number(e.left, values, time), number(e.right, values, time)
        return None if a is None or b is None else FUNCTIONS[e.op](a, b)
    if isinstance(e, Arith):
        a, b = number(e.left, values, time), number(e.right, values, time)
        if a is None or b is None:
            return None
        if e.op == "/" and b == 0:
            return None  # undefined: unknown, never a violation
        return _ARITH[e.op](a, b)
    raise TypeError(type(e).__name__)


def sqrt(x: Any) -> Any:
    """√x, exact for the square of an exact number (`sqrt(9/4)` is 3/2); ValueError below 0."""
    if isinstance(x, int | Fraction) and x >= 0:
        q = Fraction(x)
        n, d = math.isqrt(q.numerator), math.isqrt(q.denominator)
        if n * n == q.numerator and d * d == q.denominator:
            return n if d == 1 else Fraction(n, d)
    return math.sqrt(x)


def hypot(x: Any, y: Any) -> Any:
    """√(x² + y²), exact where `sqrt` is."""
    if isinstance(x, int | Fraction) and isinstance(y, int | Fraction):
        return sqrt(x * x + y * y)
    return math.hypot(x, y)


FUNCTIONS: dict[str, Callable[..., Any]] = {
    "abs": abs,
    "sqrt": sqrt,
    "min": min,
    "max": max,
    "hypot": hypot,
}
"""The functions a formula may call, by name: also the generated code's globals (`f_sqrt`)."""


# ---- generated two-valued fast path ------------------------------------------------------------


def reads(
    keys: list[FeatureKey], values: str, scope: dict[str, Any]
) -> tuple[dict[FeatureKey, str], list[str]]:
    """Generated code's local names for `keys` and the lines reading them from `values`; the
    keys themselves are bound in `scope` (K0, K1, …): objects, not source text."""
    names = {k: f"v{i}" for i, k in enumerate(keys)}
    scope.update({f"K{i}": k for i, k in enumerate(keys)})
    return names, [f"{names[k]} = {values}[K{i}]" for i, k in enumerate(keys)]


def compile_state(f: Formula) -> tuple[StateFn, list[FeatureKey]]:
    """A fast function for `f` and the feature keys it reads."""
    keys = features(f)
    scope: dict[str, Any] = {"slow": evaluate, "formula": f, **GLOBALS}
    names, lines = reads(keys, "values", scope)
    body = python(f, names)
    known = knowing(f, names)
    reads_ = "".join(f"    {line}\n" for line in lines)
    source = (
        f"def state(values, time=None):\n{reads_}"
        f"    if {known}:\n"
        f"        try:\n            return {body}\n"
        f"        except (ZeroDivisionError, TypeError, ValueError):\n            pass\n"
        f"    return slow(formula, values, time)\n"
    )
    exec(compile(source, f"<state {unparse(f)}>", "exec"), scope)
    return scope["state"], keys


def knowing(f: Formula, names: dict[FeatureKey, str]) -> str:
    """The generated test that `f`'s two-valued fast path applies: every value it reads is
    known (a condition's is a boolean)."""
    bools = boolean_keys(f)
    return (
        " and ".join(
            f"type({names[k]}) is bool" if k in bools else f"{names[k]} is not None"
            for k in valued(f)
        )
        or "True"
    )


def boolean_keys(f: Any) -> set[FeatureKey]:
    """The features `f` reads as conditions (their values must be booleans)."""
    if isinstance(f, Atom):
        return {key(f.feature)}
    return set().union(*(boolean_keys(child) for child in children(f)))


def python(n: Any, names: dict[FeatureKey, str]) -> str:
    """Python source for a state formula or expression, two-valued, the features read
    into the local `names`."""
    if isinstance(n, BoolConst):
        return "True" if n.value else "False"
    if isinstance(n, Observed):
        return f"({names[key(n.feature)]} is not None)"
    if isinstance(n, Fresh):
        age, limit = names[read_key(n)], n.limit
        return f"({age} is not None and {age} * {limit.denominator} <= {limit.numerator})"
    if isinstance(n, Atom | Ref | Sampled):
        return names[read_key(n)]
    if isinstance(n, Num):
        return repr(n.value) if math.isfinite(n.value) else "1e999" if n.value > 0 else "-1e999"
    if isinstance(n, Compare | Arith):
        return f"({python(n.left, names)} {n.op} {python(n.right, names)})"
    if isinstance(n, Unary):
        return f"(-{python(n.arg, names)})" if n.op == "-" else f"f_{n.op}({python(n.arg, names)})"
    if isinstance(n, Func):
        return f"f_{n.op}({python(n.left, names)}, {python(n.right, names)})"
    if isinstance(n, Str):
        return repr(n.value)
    if isinstance(n, Not):
        return f"(not {python(n.arg, names)})"
    if isinstance(n, Connective):
        a, b = python(n.left, names), python(n.right, names)
        return {
            "and": f"({a} and {b})",
            "or": f"({a} or {b})",
            "->": f"((not {a}) or {b})",
            "<->": f"({a} == {b})",
        }[n.op]
    raise TypeError(type(n).__name__)


GLOBALS = {f"f_{name}": fn for name, fn in FUNCTIONS.items()}
"""What generated code calls: `f_sqrt(x)` (it raises outside its domain; the Kleene path,
`evaluate`, says unknown)."""
