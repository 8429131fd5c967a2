"""Numbers from outside — times, durations, JSON values — made exact, finite and bounded.

A time or duration is kept exact (0.1 is 1/10, as written).  Converting an unbounded decimal
exactly can take forever (`1e999999999` has a billion digits), so a time must lie within
10**19 (epoch nanoseconds fit) and carry at most 60 decimal places; NaN and infinities are
not times.  A data value that is NaN or infinite is unknown (`datum`), never compared.
"""

from __future__ import annotations

import math
import re
from decimal import Decimal, InvalidOperation
from fractions import Fraction
from typing import Any

from ..errors import DkError

UNITS = {"ms": Fraction(1, 1000), "s": Fraction(1), "min": Fraction(60), "h": Fraction(3600)}
_DURATION = re.compile(r"\s*(.*?)\s*(ms|s|min|h)?\s*")
MAX_ADJUSTED = 18  # a time's largest decimal exponent
MIN_EXPONENT = -60  # a time's finest decimal place


def exact(value: Any, what: str = "time") -> Fraction:
    """`value` (int, float, Decimal, Fraction or decimal text) as an exact Fraction."""
    if isinstance(value, bool) or value is None:
        raise DkError(f"{what} must be a number, not {value!r}")
    if isinstance(value, int | Fraction):
        if abs(value) >= 10 ** (MAX_ADJUSTED + 1):
            raise DkError(f"{what} {_short(value)} is out of range")
        return Fraction(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise DkError(f"{what} must be finite, not {value}")
        value = Decimal(repr(value))
    elif isinstance(value, str):
        try:
            value = Decimal(value.strip())
        except (InvalidOperation, ValueError):
            raise DkError(f"{what} must be a number, not {_short(value)!r}") from None
    if not isinstance(value, Decimal):
        raise DkError(f"{what} must be a number, not {_short(value)!r}")
    if not value.is_finite():
        raise DkError(f"{what} must be finite, not {value}")
    exponent = value.as_tuple().exponent
    if value and (
        value.adjusted() > MAX_ADJUSTED or (isinstance(exponent, int) and exponent < MIN_EXPONENT)
    ):
        raise DkError(f"{what} {_short(value)} is out of range or finer than 1e{MIN_EXPONENT}")
    return Fraction(value)


def duration(value: Any, what: str = "duration") -> Fraction:
    """A duration as formulas write it: seconds as a number, or text with ms, s, min or h
    (`0.1`, `"500ms"`, `"2 min"`); exact and never negative."""
    if isinstance(value, str):
        number, unit = _DURATION.fullmatch(value).groups()  # type: ignore[union-attr]
        try:
            seconds = exact(number, what) * UNITS[unit or "s"]
        except DkError:
            raise DkError(
                f"{what}: {_short(value)!r} is not a duration (like 5, 0.1, 500ms, 2min)"
            ) from None
    else:
        seconds = exact(value, what)
    if seconds < 0:
        raise DkError(f"{what} must not be negative: {_short(value)}")
    return seconds


def datum(value: Any) -> Any:
    """A sample value as compared: NaN and infinities are unknown (None)."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def decimal(value: Fraction | int) -> str:
    """An exact number as a person (and the formula grammar) writes it: a whole number, or a
    decimal without exponent when the number is a finite decimal (nanosecond times and the
    bounds a formula writes are); a fraction (`1/3`) otherwise."""
    if not isinstance(value, Fraction) or value.denominator == 1:
        return str(int(value))
    digits = _decimals(value.denominator)
    if digits is None:
        return str(value)
    whole, part = divmod(abs(value.numerator) * 10**digits // value.denominator, 10**digits)
    return f"{'-' if value < 0 else ''}{whole}.{part:0{digits}d}".rstrip("0")


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


def _short(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 40 else text[:20] + "…" + text[-10:]
