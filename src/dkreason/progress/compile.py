"""Formula AST → node graph, compiled once per formula, subterms shared across formulas.

Formulas arrive without quantifiers (a plan's trees, expand.py); implication becomes
`not a or b`; every maximal temporal-free subformula becomes one generated `StateNode`.  Each
node quotes the subformula it was made for (`unparse`), as written, not as compiled.
`general.py` runs the graphs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from fractions import Fraction
from typing import Any

from ..errors import DkError
from ..parse.formula import (
    Connective,
    Formula,
    Interval,
    Not,
    Temporal,
    Until,
    unparse,
)
from .nodes import (
    BoolNode,
    Ctx,
    NextNode,
    Node,
    NotNode,
    PastNode,
    StateNode,
    UntilNode,
    WindowNode,
)
from .state import compile_state, is_state
from .witness import Clock, Time

PAST = {"historically", "once", "previous"}


def exact(value: Fraction | None) -> Time | None:
    """Interval bounds as ints where they are whole (fast arithmetic), Fractions otherwise."""
    if value is None:
        return None
    return value.numerator if value.denominator == 1 else value


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


class Graph:
    """One shared node graph for formulas that start at the same state."""

    def __init__(self, clock: Clock, timer: Callable[[Time], None] | None = None) -> None:
        self.ctx = Ctx(clock, timer)
        self.cache: dict[Formula, Node] = {}

    def node(self, f: Formula) -> Node:
        if f in self.cache:
            return self.cache[f]
        made = self._make(f)
        self.cache[f] = made
        return made

    def rank(self) -> None:
        """Fix the order its nodes tick in (nodes.order), once: a graph that runs takes no
        more formulas."""
        for n, node in enumerate(sorted(self.cache.values(), key=lambda n: (n.level, n.text))):
            node.rank = n

    def text(self, f: Formula) -> str:
        """How a witness names `f` (in seconds, whatever the stream's unit)."""
        return unparse(f, self.ctx.clock.unit)

    def _make(self, f: Formula) -> Node:
        ctx, text = self.ctx, self.text(f)
        if is_state(f):
            fn, keys = compile_state(f)
            return StateNode(ctx, fn, keys, text)
        if isinstance(f, Not):
            return NotNode(ctx, self.node(f.arg), text)
        if isinstance(f, Connective):
            said: str | None = None  # for `or`: what held when it is false
            if f.op == "->":
                said = self.text(f.left)
                return BoolNode(ctx, "or", self.node(Not(f.left)), self.node(f.right), said, text)
            if f.op == "or":
                a = f.left
                said = self.text(a.arg if isinstance(a, Not) else Not(a))
            return BoolNode(ctx, f.op, self.node(f.left), self.node(f.right), said, text)
        if isinstance(f, Temporal):
            lo, hi = exact(f.interval.lo), exact(f.interval.hi)
            child = self.node(f.arg)
            assert lo is not None
            if f.op in ("eventually", "always"):
                return WindowNode(ctx, f.op, lo, hi, child, text)
            if f.op == "next":
                return NextNode(ctx, lo, hi, child, text)
            return PastNode(ctx, f.op, lo, hi, None, child, text)
        if isinstance(f, Until):
            lo, hi = exact(f.interval.lo), exact(f.interval.hi)
            assert lo is not None
            left, right = self.node(f.left), self.node(f.right)
            if f.op == "until":
                return UntilNode(ctx, lo, hi, left, right, text)
            return PastNode(ctx, "since", lo, hi, left, right, text)
        raise DkError(f"cannot monitor {type(f).__name__}")
