"""Terms over a feature's samples (`prev(X)`, `delta(X)`, `rate(X)`, `age(X)`): what a state
carries for them, and how it is computed from a feature's last two samples.

A state holds each term a formula reads as a value of its own, under `term_key` (`rate(Yaw[r1])`,
never a feature's name: those have no parentheses), so the progression engines read it as any
feature's value and a witness shows it as written.  Whoever makes the states computes them: the
stream processor from each feature's samples (valid times), or `Samples` from the states
themselves (a state file: each state where a feature has a value is a sample of it).  Either
way a feature keeps its last two samples, no more.
"""

from __future__ import annotations

from collections.abc import Iterable
from fractions import Fraction
from typing import Any

from ..model import FeatureKey

TERMS = ("prev", "delta", "rate", "age")
Sample = tuple[Any, Any]  # (valid time in stream units, value)


def term_key(op: str, feature: FeatureKey) -> FeatureKey:
    """The state's key of a term over `feature`'s samples: `rate(Yaw[r1])`."""
    return FeatureKey(f"{op}({feature})")


def term_value(
    op: str, now: Any, last: Sample | None, prev: Sample | None, unit: Fraction | int
) -> Any:
    """The term at time `now` from the last sample and the one before it (None: none yet);
    times in stream units of `unit` seconds.  Exact where the inputs are; unknown (None)
    without the samples it needs, for values that do not subtract, or a rate over no time."""
    if last is None:
        return None
    if op == "age":
        return (now - last[0]) * unit
    if prev is None:
        return None
    if op == "prev":
        return prev[1]
    try:
        delta = last[1] - prev[1]
    except TypeError:  # strings, or a value missing
        return None
    if op == "delta":
        return delta
    dt = (last[0] - prev[0]) * unit
    return None if dt == 0 else delta / dt


class Samples:
    """Each feature's last two samples, read from the states themselves, and the terms over
    them written into each state (for states that do not carry them: a state file)."""

    def __init__(self, unit: Fraction | int) -> None:
        self.unit = unit
        self.terms: dict[FeatureKey, tuple[str, FeatureKey]] = {}
        self.kept: dict[FeatureKey, tuple[Sample | None, Sample | None]] = {}

    def want(self, terms: Iterable[tuple[str, FeatureKey]]) -> None:
        for op, feature in terms:
            self.terms[term_key(op, feature)] = (op, feature)
            self.kept.setdefault(feature, (None, None))

    def fill(self, now: Any, values: dict[FeatureKey, Any]) -> None:
        """A state at `now`: a feature with a value is sampled at it; its terms are written in."""
        kept = self.kept
        for feature, (last, _) in kept.items():
            v = values[feature]
            if v is not None and (last is None or last[0] != now):
                kept[feature] = ((now, v), last)
        for k, (op, feature) in self.terms.items():
            last, prev = kept[feature]
            values[k] = term_value(op, now, last, prev, self.unit)
