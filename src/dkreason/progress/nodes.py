"""The general progression engine: one node per distinct subformula, shared by every formula.

Demand-driven: a parent *requests* a child's value at the current position and gets True,
False, None (unknown: a final Kleene value) or PENDING, in which case the child *delivers* the
value later.  Future operators keep their undecided positions with absolute time windows and
decide each as soon as the prefix forces it (a window closes at the state whose time equals its
end); past operators keep the bounded history their windows need.  Kleene logic is monotone, so
a value computed with pending children read as unknown is final whenever it is True or False.

Every node has a `level` (leaves 0): each state ticks the nodes with open work in level order,
and `finish` settles the end of the stream the same way, children before parents.  A decided
value comes with its reason, phrased by witness.py; a value returned at once is explained on
demand (`explain`), at the same state.

Between states, `advance(t)` says the stream passed t without a state: a window that ended by
then closes (no state can fall in it any more).  A future operator with a bounded window
says, through the graph's `timer`, by when that may be worth asking: when its first waiting
position comes (it waits for nothing earlier, and later ones only end later).
"""

from __future__ import annotations

import bisect
import operator
from collections import deque
from collections.abc import Callable
from typing import Any, Protocol

from ..model import FeatureKey
from .state import StateFn, kleene
from .witness import (
    Clock,
    Time,
    Why,
    but,
    cut_of,
    next_late,
    settled,
    state_was,
    window_closed,
    window_cut,
)


class _Pending:
    __slots__ = ()

    def __repr__(self) -> str:
        return "PENDING"


PENDING: Any = _Pending()


class Waiter(Protocol):
    def deliver(self, key: Any, value: Any, why: Why | None) -> None: ...


class Ctx:
    """What every node of one graph sees: the current position, time and state; at the end,
    `cut`: the end of the data, past which a bounded window stays undecided (None: every
    window closes at the last state, by the finite-trace semantics); `timer`, told the time by
    which a waiting position's window ends (engine.Timer)."""

    def __init__(self, clock: Clock, timer: Callable[[Time], None] | None = None) -> None:
        self.pos = -1
        self.now: Time = 0
        self.values: dict[FeatureKey, Any] = {}
        self.start = 0
        self.clock = clock
        self.ticking: set[Node] = set()
        self.cut: Time | None = None
        self.timer = timer

    def waits(self, t: Time, hi: Time | None) -> None:
        """A first position waits from t, its window ending at t + hi."""
        if self.timer is not None and hi is not None:
            self.timer(t + hi)

    def cuts(self, ti: Time, hi: Time | None) -> bool:
        """At the end: whether the window of the position at ti, to ti + hi, reaches past the
        end of the data (an unbounded one never does: it keeps its finite-trace value)."""
        return self.cut is not None and hi is not None and ti + hi > self.cut


class Node:
    """`text`: the subformula as a witness quotes it (`parse.formula.unparse`)."""

    level = 0
    rank = 0  # its place in `order`

    def __init__(self, ctx: Ctx, text: str) -> None:
        self.ctx, self.text = ctx, text
        self.waiters: dict[int, list[tuple[Waiter, Any]]] = {}

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        raise NotImplementedError

    def explain(self, t: Time, value: Any) -> Why:
        """The reason for the value this node returned at once at the current position (its
        delivered values come with theirs)."""
        return settled(self.text, t, value, None, self.ctx.clock)

    def tick(self) -> None:
        pass

    def advance(self, t: Time) -> None:
        """No state until after t: what that decides (future operators)."""

    def deadline(self) -> Time | None:
        """The earliest end of a waiting position's window (None: none waits for one)."""
        return None

    def finish(self) -> None:
        pass

    def _wait(self, i: int, waiter: Waiter, key: Any) -> Any:
        self.waiters.setdefault(i, []).append((waiter, key))
        return PENDING

    def _resolve(self, i: int, value: Any, why: Why | None) -> None:
        for waiter, key in self.waiters.pop(i, ()):
            waiter.deliver(key, value, why)

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        raise NotImplementedError


order = operator.attrgetter("rank")
"""The order nodes tick and finish in (`Graph.rank` sets it): children before parents, and
among equals by text, so which of two decisions comes first (and so a witness) depends on
neither a set's order nor what else shares the graph."""


class StateNode(Node):
    """A temporal-free subformula: decided at once from the current state."""

    def __init__(self, ctx: Ctx, fn: StateFn, keys: list[FeatureKey], text: str) -> None:
        super().__init__(ctx, text)
        self.fn, self.keys = fn, keys
        self.pos = -1
        self.value: Any = None

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if self.pos != i:
            self.pos, self.value = i, self.fn(self.ctx.values, t)
        return self.value

    def explain(self, t: Time, value: Any) -> Why:
        return state_was(self.text, t, self.value, self.keys, self.ctx.values, self.ctx.clock)


class NotNode(Node):
    def __init__(self, ctx: Ctx, child: Node, text: str) -> None:
        super().__init__(ctx, text)
        self.child, self.level = child, child.level + 1

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i in self.waiters:
            return self._wait(i, waiter, key)
        v = self.child.request(i, t, self, (i, t))
        if v is PENDING:
            return self._wait(i, waiter, key)
        return None if v is None else not v

    def explain(self, t: Time, value: Any) -> Why:
        return self.child.explain(t, None if value is None else not value)

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        self._resolve(key[0], None if value is None else not value, why)


class BoolNode(Node):
    """and, or, <->: short-circuits on a decisive child, waits for pending ones.

    `said` (`or` only) is what held when it is false, as a witness says it: `A` for
    `A -> B` (compiled as `not A or B`), for `not A or B` too, and `not (A)` for `A or B`."""

    def __init__(
        self, ctx: Ctx, op: str, left: Node, right: Node, said: str | None, text: str
    ) -> None:
        super().__init__(ctx, text)
        self.op, self.left, self.right, self.said = op, left, right, said
        self.level = max(left.level, right.level) + 1
        self.open: dict[int, list[Any]] = {}
        self.decisive = {"and": False, "or": True}.get(op)
        self.sides: tuple[Any, Any] = (PENDING, PENDING)  # behind the last value returned at once

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i in self.waiters:
            return self._wait(i, waiter, key)
        a = self.left.request(i, t, self, (i, 0))
        if a is self.decisive:
            self.sides = (a, PENDING)
            return a
        b = self.right.request(i, t, self, (i, 1))
        value = self._combine(a, b)
        if value is not PENDING:
            self.sides = (a, b)
            return value
        self.open[i] = [a, b, t]
        return self._wait(i, waiter, key)

    def _combine(self, a: Any, b: Any) -> Any:
        if self.decisive is not None and (a is self.decisive or b is self.decisive):
            return self.decisive
        if a is PENDING or b is PENDING:
            return PENDING
        return kleene(self.op, a, b)

    def explain(self, t: Time, value: Any) -> Why:
        a, b = self.sides
        if value is not None and value is self.decisive:
            return (self.left if a is value else self.right).explain(t, value)
        return self._why(t, value, self.right.explain(t, b))

    def _why(self, t: Time, value: Any, right: Why) -> Why:
        """The reason for a value both sides gave, the right one's reason `right`."""
        if value is False and self.said is not None:
            return but(self.said, t, right, self.ctx.clock)
        return right

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        i, side = key
        record = self.open.get(i)
        if record is None:
            return  # decided already by the other side
        record[side] = value
        result = self._combine(record[0], record[1])
        if result is not PENDING:
            del self.open[i]
            if side == 1 and why is not None:  # the right side settled it, the left was known
                why = self._why(record[2], result, why)
            self._resolve(i, result, why)


class WindowNode(Node):
    """eventually_[a,b] (decisive True) and always_[a,b] (decisive False) in O(1) amortised:
    positions wait with absolute windows [t+a, t+b]; a decisive child value settles every
    waiting position whose window holds it, and a window closes at the state reaching its end.
    A position the child was unknown for keeps why, when a window the end of the data cut off
    left it unknown."""

    def __init__(
        self, ctx: Ctx, op: str, lo: Time, hi: Time | None, child: Node, text: str
    ) -> None:
        super().__init__(ctx, text)
        self.decisive = op == "eventually"
        self.lo, self.hi, self.child = lo, hi, child
        self.level = child.level + 1
        self.times: list[Time] = []  # waiting positions, by time
        self.entries: list[list[Any]] = []  # [position, time, unknown? (False, True, a cut)]
        self.child_open: dict[int, Time] = {}  # child positions requested but not delivered
        self.asked = -1
        self.asked_value: Any = None

    # the child's value at the current position, asked at most once per position
    def _child_now(self, j: int, t: Time) -> Any:
        if self.asked != j:
            self.asked = j
            self.asked_value = self.child.request(j, t, self, (j, t))
            if self.asked_value is PENDING:
                self.child_open[j] = t
        return self.asked_value

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i in self.waiters:
            return self._wait(i, waiter, key)
        unknown = False
        if self.lo == 0:
            v = self._child_now(i, t)
            if v is self.decisive:
                return v
            if self.hi == 0 and v is not PENDING:
                return v
            unknown = v is None
        if not self.entries:
            self.ctx.waits(t, self.hi)
        self.times.append(t)
        self.entries.append([i, t, unknown])
        self.ctx.ticking.add(self)
        return self._wait(i, waiter, key)

    def tick(self) -> None:
        ctx = self.ctx
        if self.entries:
            t = ctx.now
            first = bisect.bisect_left(self.times, t - self.hi) if self.hi is not None else 0
            if first < len(self.times) and self.times[first] <= t - self.lo:
                v = self._child_now(ctx.pos, t)
                if v is not PENDING:
                    self._apply(t, v, None)
            self._close()
        if not self.entries and not self.child_open:
            ctx.ticking.discard(self)

    def _apply(self, tj: Time, v: Any, why: Why | None) -> None:
        """Child value v at time tj: settle or mark the waiting positions whose window holds tj."""
        if v is not self.decisive and v is not None:
            return
        first = bisect.bisect_left(self.times, tj - self.hi) if self.hi is not None else 0
        last = bisect.bisect_right(self.times, tj - self.lo)
        if first >= last:
            return
        if v is None:
            cut = cut_of(why) or True
            for entry in self.entries[first:last]:
                if not isinstance(entry[2], Why):
                    entry[2] = cut
            return
        done = self.entries[first:last]
        del self.entries[first:last], self.times[first:last]
        cause = why or self.child.explain(tj, v)
        for i, ti, _ in done:
            self._resolve(i, v, settled(self.text, ti, v, cause, self.ctx.clock))

    def explain(self, t: Time, value: Any) -> Why:
        if value is not None and value is self.decisive:  # the child's value now decided it
            return settled(self.text, t, value, self.child.explain(t, value), self.ctx.clock)
        return self._closed(t, value)  # a window [t, t], closed at once

    def _closed(self, ti: Time, value: Any) -> Why:
        clock = self.ctx.clock
        return window_closed(self.text, self.child.text, ti, self.lo, self.hi, value, clock)

    def advance(self, t: Time) -> None:
        self._close(passed=t)

    def deadline(self) -> Time | None:
        return self.times[0] + self.hi if self.times and self.hi is not None else None

    def _close(self, at_end: bool = False, passed: Time | None = None) -> None:
        """Settle the waiting positions whose windows closed: at the current state, by
        `passed` (no state until after it), or at the end."""
        ctx = self.ctx
        now, pos = ctx.now, ctx.pos
        oldest_open = min(self.child_open.values()) if self.child_open else None
        while self.entries:
            i, ti, unknown = self.entries[0]
            hi = None if self.hi is None else ti + self.hi
            if not at_end:
                if hi is None or (
                    hi > passed
                    if passed is not None
                    else hi > now or (hi == now and self.asked != pos)
                ):
                    break
                if oldest_open is not None and oldest_open <= hi:
                    break
            del self.entries[0], self.times[0]
            if at_end and ctx.cuts(ti, self.hi):
                assert self.hi is not None and ctx.cut is not None
                cut = window_cut(self.text, ti, self.lo, self.hi, ctx.cut, ctx.clock)
                self._resolve(i, None, cut)
                continue
            value = None if unknown else (not self.decisive)
            self._resolve(
                i, value, unknown if isinstance(unknown, Why) else self._closed(ti, value)
            )

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        j, tj = key
        self.child_open.pop(j, None)
        self._apply(tj, value, why)
        self._close()

    def finish(self) -> None:
        self._close(at_end=True)


class NextNode(Node):
    """next_[a,b]: decided when the next state arrives (false if none does)."""

    def __init__(self, ctx: Ctx, lo: Time, hi: Time | None, child: Node, text: str) -> None:
        super().__init__(ctx, text)
        self.lo, self.hi, self.child = lo, hi, child
        self.level = child.level + 1
        self.waiting: list[tuple[int, Time]] = []

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i not in self.waiters:
            if not self.waiting:
                self.ctx.waits(t, self.hi)
            self.waiting.append((i, t))
            self.ctx.ticking.add(self)
        return self._wait(i, waiter, key)

    def advance(self, t: Time) -> None:
        """The next state comes after t: later than the window of a position whose window
        ended by then."""
        if self.hi is None:
            return
        late = [(i, ti) for i, ti in self.waiting if t - ti >= self.hi]
        if late:
            self.waiting = [w for w in self.waiting if w not in late]
            for i, ti in late:
                self._resolve(i, False, next_late(self.text, ti, None, self.ctx.clock))

    def deadline(self) -> Time | None:
        if self.hi is None or not self.waiting:
            return None
        return min(ti for _, ti in self.waiting) + self.hi

    def tick(self) -> None:
        now, pos = self.ctx.now, self.ctx.pos
        ready = [(i, ti) for i, ti in self.waiting if i == pos - 1]
        self.waiting = [(i, ti) for i, ti in self.waiting if i != pos - 1]
        for i, ti in ready:
            gap = now - ti
            if gap < self.lo or (self.hi is not None and gap > self.hi):
                self._resolve(i, False, next_late(self.text, ti, gap, self.ctx.clock))
                continue
            v = self.child.request(pos, now, self, i)
            if v is not PENDING:
                self._resolve(i, v, self.child.explain(now, v))
        if not self.waiting:
            self.ctx.ticking.discard(self)

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        self._resolve(key, value, why)

    def finish(self) -> None:
        ctx = self.ctx
        for i, ti in self.waiting:
            if ctx.cuts(ti, self.hi):
                assert self.hi is not None and ctx.cut is not None
                self._resolve(
                    i, None, window_cut(self.text, ti, self.lo, self.hi, ctx.cut, ctx.clock)
                )
            else:
                self._resolve(i, False, next_late(self.text, ti, None, ctx.clock))
        self.waiting = []


class UntilNode(Node):
    """φ until_[a,b] ψ: waiting positions are re-evaluated over the history of (φ, ψ) values
    with pending values read as unknown; a True or False result is final (Kleene monotony)."""

    def __init__(
        self, ctx: Ctx, lo: Time, hi: Time | None, left: Node, right: Node, text: str
    ) -> None:
        super().__init__(ctx, text)
        self.lo, self.hi, self.left, self.right = lo, hi, left, right
        self.level = max(left.level, right.level) + 1
        self.hist: dict[int, list[Any]] = {}  # position → [time, φ, ψ]
        self.entries: list[tuple[int, Time]] = []
        self.seen = -1

    def _record(self, j: int, t: Time) -> None:
        if self.seen == j:
            return
        self.seen = j
        row: list[Any] = [t, PENDING, PENDING]
        self.hist[j] = row
        row[1] = self.left.request(j, t, self, (j, 1))
        row[2] = self.right.request(j, t, self, (j, 2))

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i in self.waiters:
            return self._wait(i, waiter, key)
        self._record(i, t)
        value = self._evaluate(i, t, at_end=False)
        if value is not PENDING:
            self._trim()
            return value
        if not self.entries:
            self.ctx.waits(t, self.hi)
        self.entries.append((i, t))
        self.ctx.ticking.add(self)
        return self._wait(i, waiter, key)

    def advance(self, t: Time) -> None:
        self._settle(at_end=False, passed=t)

    def deadline(self) -> Time | None:
        return self.entries[0][1] + self.hi if self.entries and self.hi is not None else None

    def _evaluate(self, i: int, ti: Time, at_end: bool, passed: Time | None = None) -> Any:
        """Kleene value at i with pending and not-yet-seen positions read as unknown: final if
        True or False, PENDING if unknown while anything it read may still change (no state
        comes before `passed`, when given)."""
        now = self.ctx.now if passed is None else passed
        result: Any = False
        phi: Any = True
        open_ = False
        j = i
        while True:
            row = self.hist.get(j)
            if row is None:  # not recorded yet (this state, or one to come): open unless closed
                if at_end:  # past the data: unknown if the window reaches there
                    if self.ctx.cuts(ti, self.hi):
                        result = kleene("or", result, kleene("and", None, phi))
                elif j <= self.ctx.pos or self.hi is None or now < ti + self.hi:
                    open_ = True
                    result = kleene("or", result, kleene("and", None, phi))
                break
            tj, pj, sj = row
            if self.hi is not None and tj - ti > self.hi:
                break
            open_ = open_ or pj is PENDING or sj is PENDING
            if tj - ti >= self.lo:
                result = kleene("or", result, kleene("and", None if sj is PENDING else sj, phi))
                if result is True:
                    return True
            phi = kleene("and", phi, None if pj is PENDING else pj)
            if phi is False:
                break
            j += 1
        if result is False:
            return False
        return PENDING if open_ else None

    def tick(self) -> None:
        self._record(self.ctx.pos, self.ctx.now)
        self._settle(at_end=False)

    def _settle(self, at_end: bool, passed: Time | None = None) -> None:
        ctx, still = self.ctx, []
        for i, ti in self.entries:
            value = self._evaluate(i, ti, at_end, passed)
            if value is PENDING:
                still.append((i, ti))
            elif at_end and value is None and ctx.cuts(ti, self.hi):
                assert self.hi is not None and ctx.cut is not None
                self._resolve(
                    i, None, window_cut(self.text, ti, self.lo, self.hi, ctx.cut, ctx.clock)
                )
            else:
                self._resolve(i, value, settled(self.text, ti, value, None, ctx.clock))
        self.entries = still
        self._trim()
        if not self.entries:
            self.ctx.ticking.discard(self)

    def _trim(self) -> None:
        keep = min((i for i, _ in self.entries), default=self.ctx.pos)  # requests may come now
        for j in [j for j in self.hist if j < keep]:
            del self.hist[j]

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        j, side = key
        if j in self.hist:
            self.hist[j][side] = value
        self._settle(at_end=False)

    def finish(self) -> None:
        self._settle(at_end=True)


class PastNode(Node):
    """once / historically / since / previous over the history their windows need.

    The children are asked at every position.  A request at position i folds the history
    backwards (pending values read as unknown) and waits only while that leaves it open.
    Bounded windows drop rows older than any future window; unbounded ones fold settled rows
    into a running Kleene aggregate, so memory stays bounded either way."""

    def __init__(
        self,
        ctx: Ctx,
        op: str,
        lo: Time,
        hi: Time | None,
        left: Node | None,
        right: Node,
        text: str,
    ) -> None:
        super().__init__(ctx, text)
        self.op, self.lo, self.hi, self.left, self.right = op, lo, hi, left, right
        self.level = max(right.level, left.level if left else 0) + 1
        self.hist: deque[list[Any]] = deque()  # [position, time, φ (since), ψ]
        self.entries: list[tuple[int, Time]] = []
        self.decisive = op != "historically"
        self.folded: Any = not self.decisive  # aggregate over rows dropped from the front
        ctx.ticking.add(self)
        self.seen = -1

    def tick(self) -> None:
        j, t = self.ctx.pos, self.ctx.now
        if self.seen == j:
            return
        self.seen = j
        row: list[Any] = [j, t, True, PENDING]
        self.hist.append(row)
        if self.left is not None:
            row[2] = self.left.request(j, t, self, (j, 2))
        row[3] = self.right.request(j, t, self, (j, 3))
        self._settle()
        self._forget()

    def _forget(self) -> None:
        t = self.ctx.now
        oldest_open = min([t, *(ti for _, ti in self.entries)])  # earliest time still asked
        if self.op == "previous":
            first = min([self.ctx.pos, *(i for i, _ in self.entries)]) - 1
            while self.hist and self.hist[0][0] < first:
                self.hist.popleft()
        elif self.hi is not None:  # rows older than every open window are never read again
            while self.hist and self.hist[0][1] < oldest_open - self.hi:
                self.hist.popleft()
        else:  # settled rows inside every open window fold into the aggregate
            while (
                len(self.hist) > 1
                and self.hist[0][1] <= oldest_open - self.lo
                and PENDING not in self.hist[0][2:]
            ):
                _, _, pj, sj = self.hist.popleft()
                if self.op == "since":
                    self.folded = kleene("or", sj, kleene("and", pj, self.folded))
                else:
                    self.folded = kleene("or" if self.decisive else "and", self.folded, sj)

    def request(self, i: int, t: Time, waiter: Waiter, key: Any) -> Any:
        if i in self.waiters:
            return self._wait(i, waiter, key)
        self.tick()
        value = self._evaluate(i, t)
        if value is not PENDING:
            return value
        self.entries.append((i, t))
        return self._wait(i, waiter, key)

    def _evaluate(self, i: int, ti: Time) -> Any:
        if self.op == "previous":
            row = next((r for r in self.hist if r[0] == i - 1), None)
            if i == self.ctx.start or row is None:
                return False
            gap = ti - row[1]
            if gap < self.lo or (self.hi is not None and gap > self.hi):
                return False
            return row[3]
        combine = "or" if self.decisive else "and"
        result: Any = not self.decisive
        phi: Any = True
        open_ = False
        for j, tj, pj, sj in reversed(self.hist):
            if j > i:
                continue
            if self.hi is not None and ti - tj > self.hi:
                break
            open_ = open_ or pj is PENDING or sj is PENDING
            if ti - tj >= self.lo:
                s = None if sj is PENDING else sj
                result = kleene(combine, result, s if self.op != "since" else kleene("and", s, phi))
                if result is self.decisive:
                    return result
            if self.op == "since":
                phi = kleene("and", phi, None if pj is PENDING else pj)
                if phi is False:
                    break
        else:
            if self.hi is None:  # rows folded away all lie in every window
                tail = self.folded if self.op != "since" else kleene("and", self.folded, phi)
                result = kleene(combine, result, tail)
        if result is None and open_:
            return PENDING
        return result

    def _settle(self) -> None:
        still = []
        for i, ti in self.entries:
            value = self._evaluate(i, ti)
            if value is PENDING:
                still.append((i, ti))
            else:
                self._resolve(i, value, settled(self.text, ti, value, None, self.ctx.clock))
        self.entries = still

    def deliver(self, key: Any, value: Any, why: Why | None) -> None:
        j, side = key
        for row in self.hist:
            if row[0] == j:
                row[side] = value
        self._settle()

    def finish(self) -> None:
        self._settle()
