"""The stream clock's unit: integer nanoseconds inside, seconds at every edge a person or a
caller sees (events, policies, pushed samples)."""

from __future__ import annotations

from typing import Any

from ..errors import DkError
from ..inputs.numbers import exact

NS = 10**9
LATEST = 10**11  # s, about the year 5100: a time past it is nanoseconds given as seconds


def to_ns(seconds: Any, what: str = "time") -> int:
    """Exact seconds (JSON decimals, ints, Fractions) → integer nanoseconds, rounded to the
    nearest (`0.30000000000000004`, a float's `3 * 0.1`, is 0.3 s)."""
    value = exact(seconds, what)
    if abs(value) >= LATEST:
        raise DkError(
            f"{what} {seconds} is past the year 5000 in seconds: times are seconds "
            f"(nanoseconds given? divide by 1e9)"
        )
    return round(value * NS)


def seconds(ns: int) -> float | int:
    """Nanoseconds as the seconds people read (an int when whole)."""
    return ns // NS if ns % NS == 0 else ns / NS


def seconds_text(ns: int) -> str:
    """Nanoseconds as exact decimal seconds, for a message (`12.5`, `-0.000000001`)."""
    sign, ns = ("-", -ns) if ns < 0 else ("", ns)
    return f"{sign}{ns // NS}.{ns % NS:09d}".rstrip("0").rstrip(".")


def since(t: float | int) -> str:
    """A time from the start of the recording (`t`, s) as people read it: `t+12.3 s`, or
    `t-0.02 s` for a header stamped before the recording's first record."""
    return f"t{int(t) if t == int(t) else t:+} s"
