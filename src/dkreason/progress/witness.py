"""Witnesses, phrased in one place for both engines.

A decision's reason is a chain of `Why` links ("X is false at 3, because …").  Each kind of
link is made here (a state formula's value, a window that closed, a value its subformula
settled, a trigger whose response failed), and so is the verdict's witness text, so the same
formula and trace read the same whichever engine judged them (tests/test_progress.py checks
it on random formulas and traces).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from fractions import Fraction
from typing import Any

from ..model import FeatureKey

Time = int | Fraction


class Why:
    """Why a value was decided at a position: built only on decisions.  `plain` links only
    restate a value ("X is false at 3"); their cause says why."""

    __slots__ = ("text", "at", "detail", "cause", "plain")

    def __init__(
        self, text: str, at: Time, detail: str, cause: Why | None = None, plain: bool = False
    ) -> None:
        self.text, self.at, self.detail, self.cause, self.plain = text, at, detail, cause, plain

    def render(self) -> str:
        own = f"{self.text} {self.detail}"
        return own if self.cause is None else f"{own}, because {self.cause.render()}"

    def __repr__(self) -> str:
        return f"Why({self.render()!r})"


def fmt(t: Time | None, unit: Fraction | int = 1) -> str:
    """A time for people: in seconds (`unit` is the seconds per time unit of the stream)."""
    if t is None:
        return "oo"
    if unit != 1:
        t = Fraction(t) * unit
    if isinstance(t, Fraction):
        if t.denominator == 1:
            return str(t.numerator)
        as_float = float(t)
        if Fraction(repr(as_float)) == t:
            return repr(as_float)
        digits = _decimals(t.denominator)  # exact when it is a finite decimal (ns times are)
        if digits is None:
            return str(t)
        whole, part = divmod(abs(t.numerator) * 10**digits // t.denominator, 10**digits)
        return f"{'-' if t < 0 else ''}{whole}.{part:0{digits}d}".rstrip("0")
    return str(t)


def _decimals(denominator: int) -> int | None:
    """Digits after the point that show 1/denominator exactly; None if no number does."""
    twos = fives = 0
    while denominator % 2 == 0:
        denominator //= 2
        twos += 1
    while denominator % 5 == 0:
        denominator //= 5
        fives += 1
    return max(twos, fives) if denominator == 1 else None


def word(value: Any) -> str:
    return {True: "true", False: "false", None: "unknown"}.get(value, "pending")


def operator_text(op: str, interval: str, child: str) -> str:
    """How a witness names a temporal operator over a subformula: `eventually[0, 2] (Q)`."""
    return f"{op}{interval} ({child})"


def state_was(
    text: str,
    t: Time,
    value: bool | None,
    keys: Iterable[FeatureKey],
    values: Mapping[FeatureKey, Any],
    unit: Fraction | int,
) -> Why:
    """A state formula's value at t, with the values it read: `X > 1 was false at 3 (X = 0)`."""
    shown = ", ".join(f"{k} = {values[k]}" for k in keys)
    said = {True: "held", False: "was false", None: "was unknown"}[value]
    return Why(text, t, f"{said} at {fmt(t, unit)}" + (f" ({shown})" if shown else ""))


def settled(text: str, t: Time, value: Any, cause: Why | None, unit: Fraction | int) -> Why:
    """A subformula's value at t, for the reason `cause` gives (a plain link)."""
    return Why(text, t, f"is {word(value)} at {fmt(t, unit)}", cause, plain=True)


def window_closed(
    text: str,
    child: str,
    ti: Time,
    lo: Time,
    hi: Time | None,
    value: bool | None,
    unit: Fraction | int,
) -> Why:
    """The window [ti + lo, ti + hi] of `text` closed: its `child` never held within it
    (eventually, false), held throughout (always, true), or was unknown somewhere in it."""
    within = f"[{fmt(ti + lo, unit)}, {fmt(None if hi is None else ti + hi, unit)}]"
    how = (
        "was unknown within"
        if value is None
        else "held throughout"
        if value
        else "never held within"
    )
    return settled(text, ti, value, Why(child, ti, f"{how} {within}"), unit)


def but(trigger: str, ti: Time, why: Why, unit: Fraction | int) -> Why:
    """`A -> B` (or `not A or B`) is false at ti: A held, but `why` B did not (its plain link
    left out: the sentence says when)."""
    if why.plain and why.cause is not None:
        why = why.cause
    return Why(f"{trigger} held at {fmt(ti, unit)}, but {why.text}", why.at, why.detail, why.cause)


def next_late(text: str, ti: Time, gap: Time | None, unit: Fraction | int) -> Why:
    """`next[a, b]` is false at ti: the next state came outside [a, b] (`gap` later), or never."""
    late = f"the next state came {fmt(gap, unit)} later" if gap is not None else "no next state"
    return Why(text, ti, f"is false at {fmt(ti, unit)}: {late}")


def refuted(formula: str, why: Why) -> str:
    """A false verdict's witness: the reason for the value at the formula's first state, told
    of the formula as the user wrote it (the engine's text for it left out)."""
    return Why(formula, why.at, why.detail, why.cause).render()


def undecided(
    spans: Iterable[tuple[FeatureKey, Any, Any]], started: bool, unit: Fraction | int
) -> str:
    """An unknown verdict's witness: where the features it reads were unknown."""
    shown = ", ".join(f"{k} unknown from {fmt(a, unit)} to {fmt(b, unit)}" for k, a, b in spans)
    return "the data left it undecided: " + (
        shown if shown else "no state was seen" if not started else ""
    )
