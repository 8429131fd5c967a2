"""The general engine: any formula, as nodes of a graph shared by the parts that start at the
same state (compile.py, nodes.py), ticked once a state.  An `Engine` (engine.py)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..model import FeatureKey
from ..parse.formula import Formula
from .compile import Graph
from .engine import Report, Timer, Unknown
from .nodes import PENDING, Node, order
from .state import features
from .witness import Clock, Time, Why, settled


class Root:
    """A part: its node, requested at the part's first state; the value goes to `report`,
    with a reason about the part itself (one about a subformula, or a trigger's, is the
    cause of the part's own)."""

    __slots__ = ("node", "graph", "keys", "report", "ended", "first")

    def __init__(
        self, node: Node, graph: Graph, keys: list[FeatureKey], report: Report, ended: list[Root]
    ) -> None:
        self.node, self.graph, self.keys, self.report, self.ended = node, graph, keys, report, ended
        self.first: Time = 0

    def start(self, t: Time) -> None:
        self.first = t
        v = self.node.request(self.graph.ctx.pos, t, self, None)
        if v is not PENDING:
            self.deliver(None, v, self.node.explain(t, v) if v is False else None)

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        self.ended.append(self)
        if why is not None and why.text != self.node.text:
            why = settled(self.node.text, self.first, value, why, self.graph.ctx.clock)
        self.report(value, why)


class General:
    """The parts of any shape; `unknown` hears which features their undecided parts read
    were unknown at each state, `timer` when a window will have ended."""

    def __init__(self, clock: Clock, unknown: Unknown, timer: Timer | None = None) -> None:
        self.clock, self.unknown, self.timer = clock, unknown, timer
        self.graphs: list[Graph] = []  # those with an undecided part
        self.roots: list[Root] = []  # the undecided parts
        self.unstarted: list[Root] = []
        self.ended: list[Root] = []  # decided since the last state
        self.reads: dict[FeatureKey, None] = {}  # what the undecided parts read

    def add(self, part: Formula, report: Report) -> bool:
        if not self.graphs or self.graphs[-1].ctx.pos >= 0:
            self.graphs.append(Graph(self.clock, self.timer))
        graph = self.graphs[-1]
        root = Root(graph.node(part), graph, features(part), report, self.ended)
        self.roots.append(root)
        self.unstarted.append(root)
        self.reads.update(dict.fromkeys(root.keys))
        return True

    def step(self, pos: int, t: Time, values: Mapping[FeatureKey, Any], given: Any) -> None:
        for k in self.reads:
            if values[k] is None:  # (rare: no list made a state otherwise)
                self.unknown([k for k in self.reads if values[k] is None], pos, given)
                break
        copy = dict(values)  # the nodes may explain themselves later: a copy of their own
        for graph in self.graphs:
            ctx = graph.ctx
            if ctx.pos < 0:
                ctx.start = pos
                graph.rank()
            ctx.pos, ctx.now, ctx.values = pos, t, copy
            for node in sorted(ctx.ticking, key=order):
                node.tick()
        for root in self.unstarted:
            root.start(t)
        self.unstarted = []
        if self.ended:
            self._forget()

    def advance(self, t: Time) -> None:
        for graph in self.graphs:
            for node in sorted(graph.ctx.ticking, key=order):
                node.advance(t)
        if self.ended:
            self._forget()

    def deadline(self) -> Time | None:
        ends = [
            end
            for graph in self.graphs
            for node in graph.ctx.ticking
            if (end := node.deadline()) is not None
        ]
        return min(ends, default=None)

    def finish(self, cut: Time | None) -> None:
        for graph in self.graphs:
            graph.ctx.cut = cut
            for node in sorted(graph.cache.values(), key=order):
                node.finish()
        self._forget()

    def _forget(self) -> None:
        """Decided parts leave; so do the graphs and features only they had."""
        ended = {id(r) for r in self.ended}
        self.ended.clear()
        self.roots = [r for r in self.roots if id(r) not in ended]
        live = {id(r.graph) for r in self.roots}
        self.graphs = [g for g in self.graphs if id(g) in live]
        self.reads = {k: None for r in self.roots for k in r.keys}
