"""Formula AST → node graph, compiled once per formula, subterms shared across formulas.

Quantifiers expand over the knowledge base's objects of the sort (the matcher's expansion);
implication becomes `not a or b`; every maximal temporal-free subformula becomes one
generated `StateNode`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from fractions import Fraction
from typing import Any

from ..errors import DkError
from ..model import Arg, FeatureRef
from ..parse.formula import (
    ANY,
    MAX_EXPANSION,
    Atom,
    BoolConst,
    Connective,
    Formula,
    Interval,
    Not,
    Quant,
    Ref,
    Temporal,
    Until,
    chain,
)
from .nodes import (
    BoolNode,
    Ctx,
    NextNode,
    Node,
    NotNode,
    PastNode,
    StateNode,
    Time,
    UntilNode,
    WindowNode,
)
from .state import compile_state, features, is_state, render

Expander = Callable[[str], Sequence[str]]  # sort → object names
PAST = {"historically", "once", "previous"}


def exact(value: Fraction | None) -> Time | None:
    """Interval bounds as ints where they are whole (fast arithmetic), Fractions otherwise."""
    if value is None:
        return None
    return value.numerator if value.denominator == 1 else value


def _size(f: Any, objects: Expander) -> int:
    """Atoms and comparisons of `f` once expanded, counted without expanding."""
    if isinstance(f, Quant):
        return len(objects(f.sort)) * _size(f.body, objects)
    if isinstance(f, Connective | Until):
        return _size(f.left, objects) + _size(f.right, objects)
    if isinstance(f, Not | Temporal):
        return _size(f.arg, objects)
    return 1


def expand(f: Formula, objects: Expander | None) -> Formula:
    """Replace quantifiers by conjunctions/disjunctions over the sort's objects."""
    if isinstance(f, Quant):
        if objects is None:
            raise DkError(f"{f.span}: quantifier over {f.sort} needs a knowledge base "
                          f"(give --config)")
        size = _size(f, objects)
        if size > MAX_EXPANSION:
            raise DkError(f"{f.span}: the quantifiers expand to {size} subformulas, more than "
                          f"the {MAX_EXPANSION} one monitor takes")
        names = list(objects(f.sort))
        body = expand(f.body, objects)
        parts: list[Formula] = [_substitute(body, f.var, name) for name in names]
        op = "and" if f.op == "forall" else "or"
        return chain(op, parts) if parts else BoolConst(op == "and")
    if isinstance(f, Not):
        return Not(expand(f.arg, objects))
    if isinstance(f, Connective):
        return Connective(f.op, expand(f.left, objects), expand(f.right, objects))
    if isinstance(f, Temporal):
        return Temporal(f.op, f.interval, expand(f.arg, objects))
    if isinstance(f, Until):
        return Until(f.op, f.interval, expand(f.left, objects), expand(f.right, objects))
    return f


def _substitute(node: Any, var: str, name: str) -> Any:
    if isinstance(node, Atom | Ref):
        ref = node.feature
        args = tuple(Arg(name) if a.name == var else a for a in ref.args)
        return type(node)(FeatureRef(ref.name, args, ref.span))
    if isinstance(node, Quant):
        return node if node.var == var else replace(node, body=_substitute(node.body, var, name))
    changes = {attr: _substitute(getattr(node, attr), var, name)
               for attr in ("arg", "left", "right") if hasattr(node, attr)}
    return replace(node, **changes) if changes else node


def scaled(f: Formula, factor: Fraction) -> Formula:
    """The formula with every interval bound multiplied by `factor` (seconds → stream units)."""
    if factor == 1:
        return f
    if isinstance(f, Temporal | Until):
        hi = None if f.interval.hi is None else f.interval.hi * factor
        changes: dict[str, Any] = {"interval": Interval(f.interval.lo * factor, hi)}
    else:
        changes = {}
    for attr in ("arg", "left", "right", "body"):
        if hasattr(f, attr):
            changes[attr] = scaled(getattr(f, attr), factor)
    return replace(f, **changes) if changes else f


def interval_text(i: Interval, unit: Fraction | int = 1) -> str:
    """The interval as the formula wrote it (in seconds, whatever the stream's unit)."""
    if i == ANY:
        return ""
    return str(Interval(i.lo * unit, None if i.hi is None else i.hi * unit))


class Graph:
    """One shared node graph for formulas that start at the same state."""

    def __init__(self) -> None:
        self.ctx = Ctx()
        self.cache: dict[Formula, Node] = {}

    def node(self, f: Formula) -> Node:
        if f in self.cache:
            return self.cache[f]
        made = self._make(f)
        self.cache[f] = made
        return made

    def _make(self, f: Formula) -> Node:
        ctx = self.ctx
        if is_state(f):
            fn, keys = compile_state(f)
            return StateNode(ctx, fn, keys, render(f))
        if isinstance(f, Not):
            return NotNode(ctx, self.node(f.arg))
        if isinstance(f, Connective):
            if f.op == "->":
                return BoolNode(ctx, "or", self.node(Not(f.left)), self.node(f.right))
            return BoolNode(ctx, f.op, self.node(f.left), self.node(f.right))
        if isinstance(f, Temporal):
            lo, hi = exact(f.interval.lo), exact(f.interval.hi)
            text = interval_text(f.interval, ctx.unit)
            child = self.node(f.arg)
            assert lo is not None
            if f.op in ("eventually", "always"):
                return WindowNode(ctx, f.op, lo, hi, child, text)
            if f.op == "next":
                return NextNode(ctx, lo, hi, child, text)
            return PastNode(ctx, f.op, lo, hi, None, child, text)
        if isinstance(f, Until):
            lo, hi = exact(f.interval.lo), exact(f.interval.hi)
            text = interval_text(f.interval, ctx.unit)
            assert lo is not None
            left, right = self.node(f.left), self.node(f.right)
            if f.op == "until":
                return UntilNode(ctx, lo, hi, left, right, text)
            return PastNode(ctx, "since", lo, hi, left, right, text)
        raise DkError(f"cannot monitor {type(f).__name__}")


def formula_features(f: Formula) -> list[str]:
    """Every feature key a (quantifier-free) formula reads."""
    return features(f)

