"""A formula's verdict from its instances' (parametric monitoring, as MonPoly, RTLola and
JavaMOP slice by parameter).

A formula with outermost quantifiers (`forall c in Car:` …) is judged as one instance per
binding of their variables, each on its own state stream (monitor.py); its verdict is theirs
joined as the quantifiers say, in Kleene logic: `forall` is false as soon as one instance is
false and true once all are true, `exists` dually, and an instance whose features never had a
value is "never observed": unknown, blocking no other instance's verdict.  The verdict is
given as soon as it is decided, naming every instance (those still open as such); instances
settling after it are named again in `update`s of the same verdict, never retracted.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

from .expand import Binder
from .model import FeatureKey
from .plan import Bindings, FormulaPlan, fold
from .progress import InstanceVerdict, UnknownSpan, Verdict
from .progress.verdict import INF, Margin
from .progress.witness import SHOWN, UNDECIDED
from .stream.units import seconds

if TYPE_CHECKING:  # robustness (numpy) is loaded when asked for
    from .progress.robustness import Rho

PENDING: Any = "pending"  # an instance not settled yet: may still be anything
STATUS = {True: "held", False: "violated", None: "unknown"}
NEVER = "never observed"


class Judged:
    """One formula of a plan as it is judged: its instances' verdicts so far (times in
    seconds) and what they decide."""

    def __init__(self, formula: FormulaPlan) -> None:
        self.text = formula.text
        self.prefix: Sequence[Binder] = formula.prefix
        self.names: list[Bindings] = [i.bindings for i in formula.instances]
        self.index = {b: n for n, b in enumerate(self.names)}
        self.settled: dict[int, Verdict] = {}  # instance → its verdict
        self.said: Verdict | None = None  # the formula's, once given
        self.more = False  # instances settled since it was given

    @property
    def open(self) -> int:
        """Instances not settled yet (a formula with none left is done)."""
        return len(self.names) - len(self.settled)

    def extend(self, formula: FormulaPlan) -> list[int]:
        """The formula planned again (objects joined its sorts): its new instances, judged
        from now on beside the others, which go on as they were."""
        self.prefix = formula.prefix
        new = [i.bindings for i in formula.instances if i.bindings not in self.index]
        for bindings in new:
            self.index[bindings] = len(self.names)
            self.names.append(bindings)
        return [self.index[b] for b in new]

    def settle(
        self, verdicts: Iterable[tuple[int, Verdict]], now: tuple[Any, Any], at_end: bool = False
    ) -> list[Verdict]:
        """Instances settled at one state (`now`: its time and `t`, s), or at the end: the
        formula's verdict if this decides it, else an update if it was given already."""
        batch = list(verdicts)
        self.settled.update(batch)
        if self.said is not None:
            self.more = self.more or bool(batch)
            if not self.more or (self.open and not any(v.verdict is False for _, v in batch)):
                return []  # what settled is said with the next violation, or at the end
            self.more = False
            return [dataclasses.replace(self.said, instances=self.instances(), update=True)]
        value = self.value()
        if value is PENDING:
            return []
        self.said = self._verdict(value, batch, now, at_end)
        return [self.said]

    def value(self) -> Any:
        """The formula's value from its instances' (PENDING: not decided yet)."""
        return fold(self.prefix, self._leaf, _join)

    def _leaf(self, bindings: Bindings) -> Any:
        v = self.settled.get(self.index[bindings])
        return PENDING if v is None else v.verdict

    def instances(self) -> tuple[InstanceVerdict, ...]:
        return tuple(self._instance(n) for n in range(len(self.names)))

    def _instance(self, n: int) -> InstanceVerdict:
        v = self.settled.get(n)
        if v is None:
            return InstanceVerdict(self.names[n], None, None, False, "open")
        status = NEVER if v.verdict is None and v.time is None else STATUS[v.verdict]
        return InstanceVerdict(
            self.names[n],
            v.verdict,
            v.time,
            v.at_end,
            status,
            v.witness,
            v.pending,
            v.t,
            v.robustness,
        )

    def margin(self) -> Margin | None:
        """The formula's robustness from its instances' (when asked): the least of them for
        `forall`, the greatest for `exists`, an unknown or open one as robustness.lower and
        upper take it."""
        if not any(v.robustness is not None for v in self.settled.values()):
            return None
        from .progress.robustness import UNKNOWN, lower, upper

        def leaf(bindings: Bindings) -> Rho:
            v = self.settled.get(self.index[bindings])
            m = None if v is None else v.robustness
            return None if m is None or m.value is None else (m.value, m)

        def join(op: str, parts: list[Rho]) -> Rho:
            acc: Rho = (INF, None) if op == "forall" else (-INF, None)
            fold = lower if op == "forall" else upper
            for part in parts:
                acc = fold(acc, part)
            return acc

        found = fold(self.prefix, leaf, join)
        if found is None:
            return UNKNOWN
        m = found[1]
        return m if isinstance(m, Margin) else Margin(found[0], None)

    def _verdict(
        self,
        value: bool | None,
        batch: list[tuple[int, Verdict]],
        now: tuple[Any, Any],
        at_end: bool,
    ) -> Verdict:
        if not self.prefix:
            v = self.settled[0]
            return dataclasses.replace(v, formula=self.text)
        instances = self.instances()
        # the instance that decided it: the first in this batch with the formula's value
        deciding = next((n for n, v in batch if v.verdict is value), None)
        timed = [v for v in self.settled.values() if v.time is not None]
        last = max(timed, key=lambda v: v.time, default=None)
        time, t = now if last is None else (last.time, last.t)
        at_end = at_end or any(v.at_end for v in self.settled.values())
        witness = pending = window = None
        unknown: tuple[UnknownSpan, ...] = ()
        if value is False and deciding is not None:
            v = self.settled[deciding]
            time, t, at_end, window = v.time, v.t, v.at_end, v.window
            witness = f"{instances[deciding].name} {v.witness}"
        elif value is None:
            left = [(i, self.settled[n]) for n, i in enumerate(instances) if i.verdict is None]
            unknown = tuple(u for _, v in left for u in v.unknown)
            pending = next((v.pending for _, v in left if v.pending is not None), None)
            said = [f"{i.name}: {_reason(v.witness)}" for i, v in left]
            if len(said) > SHOWN:
                said[SHOWN:] = [f"and {len(said) - SHOWN} more"]
            witness = "the data left it undecided for " + "; ".join(said)
        elif value is True and self.prefix[0].op == "exists" and deciding is not None:
            v = self.settled[deciding]
            time, t, at_end = v.time, v.t, v.at_end
        return Verdict(
            self.text,
            value,
            time,
            at_end,
            witness,
            unknown,
            t=t,
            pending=pending,
            instances=instances,
            window=window,
            robustness=self.margin(),
        )


def _join(op: str, parts: list[Any]) -> Any:
    """Kleene `and` (forall) or `or` (exists) of instance values, PENDING ones unsettled."""
    decisive = op == "exists"
    if decisive in parts:
        return decisive
    if PENDING in parts:
        return PENDING
    return None if None in parts else not decisive


def _reason(witness: str | None) -> str:
    """What an unknown instance's witness says after its lead."""
    return (witness or "unknown").removeprefix(UNDECIDED)


# ---- unknown spans as people read them ------------------------------------------------------


def spans(
    unknown: Sequence[UnknownSpan],
    last: int,
    end: int | None,
    newest: Callable[[FeatureKey], int | None],
    max_age: int | None,
) -> list[UnknownSpan]:
    """An unknown verdict's spans (ns): a feature's spans less than `max_age` apart merged
    into one; one lasting to `last` (its group's last state) with no sample of the feature
    since it began said once, as its source silent from its last sample (`newest`; None: never
    observed) to `end`, the end of the data."""
    by_feature: dict[FeatureKey, list[UnknownSpan]] = {}
    for u in unknown:
        by_feature.setdefault(u.feature, []).append(u)
    out: list[UnknownSpan] = []
    for k, them in by_feature.items():
        merged = [them[0]]
        for u in them[1:]:
            if max_age is not None and u.start - merged[-1].end < max_age:
                merged[-1] = UnknownSpan(k, merged[-1].start, u.end)
            else:
                merged.append(u)
        tail, sample = merged[-1], newest(k)
        if tail.end == last and end is not None and (sample is None or sample < tail.start):
            merged[-1] = UnknownSpan(k, sample, max(end, tail.end), silent=True)
        out += merged
    return out


def span_seconds(u: UnknownSpan) -> UnknownSpan:
    return UnknownSpan(
        u.feature, None if u.start is None else seconds(u.start), seconds(u.end), u.silent
    )
