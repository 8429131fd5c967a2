"""The states robustness reads, kept only while a margin may still need them: memory bounded
by the formulas' windows, not by the recording.

A formula's margin is its value at its first state (robustness.py), and how much of the trace
that reads depends on its shape:

- a bounded reach (`X > 3`, `eventually[0, 5] X`): the states up to the first one past it;
  then the margin is taken once and nothing more is kept;
- `always φ` (`eventually φ`) with φ of bounded reach, the shapes monitors run most
  (`always (A -> eventually[0, 5] B)`): the least (greatest) of φ's margins so far with its
  critical atom, folded in every few thousand states over the states whose windows have
  closed, and only the open windows' states (and what φ's past operators look back on) kept;
- `not`, `and`, `or`, … of those: each part kept so, joined at the margin;
- anything else (`always eventually X`, an unbounded `until`): every state from its first.

States are shared by the formulas of one stream, kept as columns (a time list, and a list per
feature the formulas read); a fold happens when the lists have doubled since the last (at least
CHUNK states), so keeping a state costs an append per column (the fused fast step appends to
them itself: `appenders`).
"""

from __future__ import annotations

import bisect
import dataclasses
from collections.abc import Hashable, Mapping
from typing import Any

import numpy as np

from ..model import FeatureKey
from ..parse.formula import (
    Connective,
    Formula,
    Not,
    Temporal,
    Until,
    children,
)
from .engine import Append
from .robustness import Columns, Rho, Signals, at_start, lower, upper
from .state import features
from .verdict import INF
from .witness import Time

CHUNK = 4096


def reach(f: Any) -> tuple[Any, Any] | None:
    """How far ahead and back in time a formula's margin at a state reads (None: as far as
    the data goes)."""
    temporal = isinstance(f, Temporal | Until)
    if temporal and f.interval.hi is None:
        return None
    parts = [reach(c) for c in children(f)] if temporal or isinstance(f, Connective | Not) else []
    known = [p for p in parts if p is not None]
    if len(known) < len(parts):
        return None
    ahead, back = max((p[0] for p in known), default=0), max((p[1] for p in known), default=0)
    if not temporal:
        return ahead, back
    if f.op in ("always", "eventually", "next", "until"):
        return ahead + f.interval.hi, back
    return ahead, back + f.interval.hi


def _neg(r: Rho) -> Rho:
    if r is None:
        return None
    value, crit = r
    return -value, None if crit is None else dataclasses.replace(crit, value=-crit.value)


def _join(op: str, a: Rho, b: Rho) -> Rho:
    if op == "and":
        return lower(a, b)
    if op == "or":
        return upper(a, b)
    if op == "->":
        return upper(_neg(a), b)
    return lower(upper(_neg(a), b), upper(a, _neg(b)))


class Kept:
    """The states of one stream that the formulas registered (`add`) may still read."""

    def __init__(self, chunk: int = CHUNK) -> None:
        self.times: list[Time] = []
        self.columns: dict[FeatureKey, list[Any]] = {}  # what the formulas read, by feature
        self.offset = 0  # the index in the stream of times[0]
        self.parts: dict[Hashable, _Part] = {}
        self.chunk = self.fold_at = chunk
        self.last: tuple[Hashable, Signals] | None = None  # the last `window`

    @property
    def states(self) -> Columns:
        return Columns(self.times, self.columns)

    def add(self, name: Hashable, tree: Formula) -> None:
        """A formula judged from the next state on (its bounds in the stream's units)."""
        for k in features(tree):
            self.columns.setdefault(k, [None] * len(self.times))  # (none read before)
        self.parts[name] = _part(tree, self.offset + len(self.times))

    def append(self, t: Time, values: Mapping[FeatureKey, Any]) -> None:
        self.times.append(t)
        for k, column in self.columns.items():
            column.append(values[k])
        if len(self.times) >= self.fold_at:
            self.fold()

    def appenders(self) -> tuple[Append, dict[FeatureKey, Append], int]:
        """For a caller appending a state itself (the fused fast step): the time list's
        append, each column's, and how many states until `fold` is due."""
        columns = {k: c.append for k, c in self.columns.items()}
        return self.times.append, columns, self.fold_at - len(self.times)

    def fold(self) -> int:
        """Fold in what is settled, and forget the states no formula reads any more; returns
        how many states until the next fold."""
        signals = Signals(self.states)  # one reading of the columns for every formula
        for part in self.parts.values():
            part.fold(self, signals)
        end = self.offset + len(self.times)
        need = min((k for p in self.parts.values() if (k := p.keep()) is not None), default=end)
        if need > self.offset:
            del self.times[: need - self.offset]
            for column in self.columns.values():
                del column[: need - self.offset]
            self.offset = need
        self.fold_at = max(self.chunk, 2 * len(self.times))
        return self.fold_at - len(self.times)

    def margin(self, name: Hashable, upto: Time | None, end: Time | None) -> Rho:
        """A formula's margin over its states up to `upto` (None: all), a window reaching past
        `end` unknown in its unseen part (None: windows close at the last state); the formula
        is forgotten."""
        return self.parts.pop(name).value(self, upto, end)

    def time(self, i: int) -> Time:
        """The time of the state at stream index i."""
        return self.times[i - self.offset]

    def index(self, t: Time, at: int, right: bool = False) -> int:
        """The stream index of the first state from `at` on at or (`right`) after time t."""
        find = bisect.bisect_right if right else bisect.bisect_left
        return self.offset + find(self.times, t, max(at - self.offset, 0))

    def window(self, start: int, upto: Time | None, end: Time | None = None) -> Signals:
        """The margins over the kept states from stream index `start` to time `upto` (`end`:
        the data's, as Signals takes it); the formulas a state decides read the same window,
        read once."""
        stop = len(self.times) if upto is None else self.index(upto, start, True) - self.offset
        at = (self.offset, len(self.times), start, stop, end)
        if self.last is None or self.last[0] != at:
            states = self.states
            if start > self.offset or stop < len(self.times):
                states = states[start - self.offset : stop]
            self.last = (at, Signals(states, end))
        return self.last[1]

    def end(self) -> int:
        """The stream index after the last state kept."""
        return self.offset + len(self.times)


class _Part:
    def __init__(self, tree: Formula, start: int) -> None:
        self.tree, self.start = tree, start

    def fold(self, kept: Kept, signals: Signals) -> None:
        """Fold in what the states kept (`signals`: their margins) settle."""

    def keep(self) -> int | None:
        """The first stream index still read (None: none)."""
        return self.start

    def value(self, kept: Kept, upto: Time | None, end: Time | None) -> Rho:
        signals = kept.window(self.start, upto, end)
        return at_start(self.tree, signals) if signals.n else None


class _Head(_Part):
    """A formula of bounded reach: its margin once a state past the reach arrives."""

    def __init__(self, tree: Formula, start: int, ahead: Any) -> None:
        super().__init__(tree, start)
        self.ahead = ahead
        self.settled: tuple[Rho] | None = None

    def fold(self, kept: Kept, signals: Signals) -> None:
        if self.settled is not None or kept.end() <= self.start:
            return
        past = kept.index(kept.time(self.start) + self.ahead, self.start, True)
        if past < kept.end():  # windows closed: the end no longer matters
            self.settled = (at_start(self.tree, kept.window(self.start, None)),)

    def keep(self) -> int | None:
        return self.start if self.settled is None else None

    def value(self, kept: Kept, upto: Time | None, end: Time | None) -> Rho:
        return self.settled[0] if self.settled is not None else super().value(kept, upto, end)


class _Fold(_Part):
    """`always[lo, oo) φ` (`eventually`) with φ of bounded reach: the fold of φ's margins at
    the states whose windows closed, and the states the others read."""

    def __init__(self, tree: Temporal, start: int, reach_: tuple[Any, Any]) -> None:
        super().__init__(tree, start)
        self.arg, self.lo, (self.ahead, self.back) = tree.arg, tree.interval.lo, reach_
        self.minimum = tree.op == "always"
        self.empty: Rho = (INF if self.minimum else -INF, None)  # no state folded in yet
        self.acc: Rho = self.empty
        self.origin: Time | None = None  # the formula's first state's time
        self.done = start  # the states before it are folded in
        self.context = start  # the first state the next fold reads

    def fold(self, kept: Kept, signals: Signals) -> None:
        if kept.end() <= self.done:
            return
        self.origin = kept.time(self.start) if self.origin is None else self.origin
        closed = kept.index(kept.times[-1] - self.ahead, self.done)  # t + ahead < last
        if closed > self.done:
            base = kept.offset
            if self.back and base < self.start:  # past operators must not see before start
                signals, base = Signals(kept.states[self.context - base :]), self.context
            self.acc = self._fold(kept, signals, base, self.acc, closed)
            self.done = closed
            t_done = kept.time(closed)
            self.context = max(self.start, kept.index(t_done - self.back, self.context))

    def _fold(self, kept: Kept, signals: Signals, base: int, acc: Rho, stop: int) -> Rho:
        """acc folded with φ's margins at the states from `done` to `stop` (from the first at
        least lo after the formula's first state); `signals` begin at stream index `base`."""
        first = self.done
        if self.lo:
            assert self.origin is not None
            first = max(first, kept.index(self.origin + self.lo, first))
        if first >= stop:
            return acc
        rho = signals.rho(self.arg)[first - base : stop - base]
        unknown = np.isnan(rho)
        known = np.where(unknown, INF if self.minimum else -INF, rho)
        at = int(np.argmin(known) if self.minimum else np.argmax(known))
        best = float(known[at])
        if (best < 0 if self.minimum else best > 0) or not unknown.any():
            here: Rho = (best, at)
        else:
            here = None
        joined = here if acc is self.empty else (lower if self.minimum else upper)(acc, here)
        if joined is not here or here is None:
            return joined
        crit = signals.critical(self.arg, first - base + at)
        return best, None if crit is None else signals.found(crit)

    def keep(self) -> int | None:
        return self.context

    def value(self, kept: Kept, upto: Time | None, end: Time | None) -> Rho:
        signals = kept.window(self.context, upto, end)
        if kept.end() <= self.start or not signals.n:
            return None
        self.origin = signals.trace[0][0] if self.origin is None else self.origin
        return self._fold(kept, signals, self.context, self.acc, self.context + signals.n)


class _Join(_Part):
    """`not`, `and`, `or`, … of formulas each kept as its shape allows."""

    def __init__(self, tree: Not | Connective, parts: list[_Part]) -> None:
        super().__init__(tree, parts[0].start)
        self.parts = parts

    def fold(self, kept: Kept, signals: Signals) -> None:
        for p in self.parts:
            p.fold(kept, signals)

    def keep(self) -> int | None:
        return min((k for p in self.parts if (k := p.keep()) is not None), default=None)

    def value(self, kept: Kept, upto: Time | None, end: Time | None) -> Rho:
        values = [p.value(kept, upto, end) for p in self.parts]
        if isinstance(self.tree, Not):
            return _neg(values[0])
        assert isinstance(self.tree, Connective)
        return _join(self.tree.op, values[0], values[1])


def _part(f: Formula, start: int) -> _Part:
    bounded = reach(f)
    if bounded is not None:
        return _Head(f, start, bounded[0])
    if isinstance(f, Temporal) and f.op in ("always", "eventually") and f.interval.hi is None:
        inner = reach(f.arg)
        if inner is not None:
            return _Fold(f, start, inner)
    if isinstance(f, Not):
        return _Join(f, [_part(f.arg, start)])
    if isinstance(f, Connective):
        return _Join(f, [_part(f.left, start), _part(f.right, start)])
    return _Part(f, start)


__all__ = ["CHUNK", "Kept", "reach"]
