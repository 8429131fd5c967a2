"""What monitoring says of a formula: its `Verdict`, the `UnknownSpan`s that left one undecided,
and, for a formula with outer quantifiers, each instance's `InstanceVerdict` (one per binding
of their variables, judged on its own)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from decimal import Decimal
from fractions import Fraction
from typing import Any

from ..inputs.numbers import decimal
from ..model import FeatureKey

INF = float("inf")


def value_text(value: Any) -> str:
    """A value as a witness shows it: an exact one as a decimal (`2.000000001`, an age), none
    as unknown."""
    if value is None:
        return "unknown"
    return decimal(value) if type(value) is Fraction else str(value)


@dataclass(frozen=True, slots=True)
class Margin:
    """By how much a formula held (> 0) or failed (< 0): `value`, the margin of its critical
    atom `atom` at time `time`, which read `values`, each from `sources` (feature → where its
    values are read: topic, field, and the match that chose it).  `value` None: no margin,
    unknown values covering where it would be decided."""

    value: Any
    atom: str | None
    time: Any = None
    t: Any = None
    values: tuple[tuple[str, Any], ...] = ()
    sources: tuple[tuple[str, str], ...] = ()

    def text(self) -> str:
        """`violated by 3.2 at t+41 s: Altitude[uav2] > 10 (Altitude[uav2] = 6.8, read from
        platform3/uastopic5 msg.height as Alt[uas21])`."""
        if self.value is None:
            return "no margin: unknown values cover where it would be decided"
        said = "held" if self.value > 0 or self.value == 0 and _positive(self.value) else "violated"
        size = _number_text(abs(self.value))
        if self.atom is None:
            return f"{said} by {size}"
        when = f"t+{_number_text(self.t)} s" if self.t is not None else str(self.time)
        sources = dict(self.sources)
        read = ", ".join(
            f"{k} = {value_text(v)}" + (f" read from {sources[k]}" if k in sources else "")
            for k, v in self.values
        )
        return f"{said} by {size} at {when}: {self.atom}" + (f" ({read})" if read else "")

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"value": _json_number(self.value), "atom": self.atom}
        if self.value is None:
            return out | {"text": self.text()}
        if self.atom is not None:
            out |= {"time": _json_number(self.time), "t": _json_number(self.t)}
            out["values"] = {k: _json_number(v) for k, v in self.values}
            out["sources"] = dict(self.sources)
        return out


def _positive(zero: Any) -> bool:
    """A zero margin's sign: -0.0 failed by nothing (`a < b` with a = b), 0 held by it."""
    return not (isinstance(zero, float) and math.copysign(1.0, zero) < 0)


def _json_number(v: Any) -> Any:
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return v
    if isinstance(v, float):  # (a zero's sign is the verdict's business: 0, not -0.0)
        return v + 0.0 if v not in (INF, -INF) else str(v)
    return int(v) if v == int(v) else float(v)


def _number_text(v: Any) -> str:
    if v in (INF, -INF):
        return "∞" if v > 0 else "-∞"
    try:
        return decimal(v) if not isinstance(v, float) else f"{v:.6g}"
    except (TypeError, ValueError):
        return str(v)


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
    robustness: Margin | None = None  # when asked (progress.robustness)

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
        if self.robustness is not None:
            out["robustness"] = self.robustness.to_json()
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
    robustness: Margin | None = None  # when asked: by how much, and what decided it

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
        if self.robustness is not None:
            out["robustness"] = self.robustness.to_json()
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
