"""What monitoring says of a formula: its `Verdict`, the `UnknownSpan`s that left one undecided,
and, for a formula with outer quantifiers, each instance's `InstanceVerdict` (one per binding
of their variables, judged on its own)."""

from __future__ import annotations

from dataclasses import dataclass, field
from decimal import Decimal
from fractions import Fraction
from typing import Any

from ..model import FeatureKey


@dataclass(frozen=True, slots=True)
class UnknownSpan:
    """A feature unknown from `start` to `end` (the states at which it was).  `silent`: it
    stayed unknown to the end of the data (`end`), its source silent since its last sample
    (`start`; None: it was never observed)."""

    feature: FeatureKey
    start: Any
    end: Any
    silent: bool = False

    def to_json(self) -> dict[str, Any]:
        out = {
            "feature": str(self.feature),
            "from": json_time(self.start),
            "to": json_time(self.end),
        }
        return {**out, "silent": True} if self.silent else out


@dataclass(frozen=True, slots=True)
class InstanceVerdict:
    """One instance of a quantified formula: its variables' objects (local names) and its own
    verdict, decided from the first state at which every feature it reads has a value (or
    from the start time).  `status` says it in a word: held, violated, unknown (the data left
    it open), never observed (no state had its features), or open (not decided yet).  `t`:
    its time from the recording's start, as a verdict's."""

    bindings: tuple[tuple[str, str], ...]
    verdict: bool | None
    time: Any
    at_end: bool
    status: str
    witness: str | None = None
    pending: str | None = None
    t: float | int | None = None

    @property
    def name(self) -> str:
        """`c = car2` (`x = uav1, y = car3`)."""
        return ", ".join(f"{var} = {obj}" for var, obj in self.bindings)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "bindings": dict(self.bindings),
            "verdict": self.verdict,
            "status": self.status,
            "time": json_time(self.time),
            **({} if self.t is None else {"t": self.t}),
            "witness": self.witness,
        }
        if self.pending is not None:
            out["pending"] = self.pending
        return out


@dataclass(frozen=True, slots=True)
class Verdict:
    """The value of a formula at the first state, with the state that decided it.

    `at_end` is True when `finish()` settled it; `verdict` is None only then, when the data
    left it unknown (`unknown` says which features and when; `pending`, which time window the
    end of the data cut off).  A monitor over a recording also gives `t`, the time in seconds
    from the recording's start.  A formula with outer quantifiers names its `instances`; when
    some were still open at its verdict, later `update`s (the same verdict, never retracted)
    name them as they settle.  A violated verdict's `window` is its witness's span on the
    stream's clock: from the earliest time its reason names to the decision (what `--clips`
    cuts out and `--plot` shades)."""

    formula: str
    verdict: bool | None
    time: Any
    at_end: bool
    witness: str | None = None
    unknown: tuple[UnknownSpan, ...] = field(default=())
    t: float | int | None = None
    pending: str | None = None
    instances: tuple[InstanceVerdict, ...] | None = None
    update: bool = False
    window: tuple[Any, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "formula": self.formula,
            "verdict": self.verdict,
            "time": json_time(self.time),
            **({} if self.t is None else {"t": self.t}),
            "at_end": self.at_end,
            "witness": self.witness,
        }
        if self.verdict is None:
            out["unknown"] = [u.to_json() for u in self.unknown]
        if self.pending is not None:
            out["pending"] = self.pending
        if self.instances is not None:
            out["instances"] = [i.to_json() for i in self.instances]
        if self.update:
            out["update"] = True
        return out


def json_time(t: Any) -> Any:
    """A time as JSON writes it: a whole number, or a float."""
    if isinstance(t, Fraction | Decimal):
        return int(t) if t == int(t) else float(t)
    return t
