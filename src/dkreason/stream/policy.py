"""`StreamPolicy`: how samples become states (thesis listing 5.2's constraints plus the
approximation), checked when it is made and defined once for the CLI and the API alike.

Durations and times are seconds: numbers (exact as written: 0.1 is 1/10) or text with a unit
(`"500ms"`, `"2 min"`), the same as `dkreason monitor` takes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from typing import Literal

from ..errors import DkError
from ..inputs.numbers import duration, exact

Seconds = Fraction | Decimal | float | int | str
APPROXIMATIONS = ("recent", "none")
END_OF_DATA = ("open", "finite")


@dataclass(frozen=True, slots=True, init=False)
class StreamPolicy:
    """Immutable; `dataclasses.replace` makes a variant.  A bad field is one `DkError` naming
    it, raised here rather than when the first state is made."""

    sample_period: Fraction | None  # None: a state on every change
    sample_period_deviation: Fraction
    approximation: Literal["recent", "none"]
    max_age: Fraction | None  # None: a sample never gets too old
    delay_before_approximation: Fraction  # transport latency waited for before a state
    start_time: Fraction | None
    end_time: Fraction | None
    max_delay: Fraction | None
    ordered_on_valid_time: bool
    unique_valid_time: bool
    span_from_first: bool  # start_time and end_time count from the first sample
    # at the end of the data, a bounded window reaching past it stays undecided ("open"), or
    # closes as on a finite trace ("finite", the thesis' semantics)
    end_of_data: Literal["open", "finite"]

    def __init__(
        self,
        *,
        sample_period: Seconds | None = None,
        sample_period_deviation: Seconds = 0,
        approximation: Literal["recent", "none"] = "recent",
        max_age: Seconds | None = 5,
        delay_before_approximation: Seconds = "100ms",
        start_time: Seconds | None = None,
        end_time: Seconds | None = None,
        max_delay: Seconds | None = None,
        ordered_on_valid_time: bool = False,
        unique_valid_time: bool = False,
        span_from_first: bool = False,
        end_of_data: Literal["open", "finite"] = "open",
    ) -> None:
        if approximation not in APPROXIMATIONS:
            raise DkError(
                f"StreamPolicy approximation: {approximation!r} is not one of "
                f"{', '.join(APPROXIMATIONS)}"
            )
        if end_of_data not in END_OF_DATA:
            raise DkError(
                f"StreamPolicy end_of_data: {end_of_data!r} is not one of {', '.join(END_OF_DATA)}"
            )
        period = _optional(sample_period, "sample_period")
        if period == 0:
            raise DkError("StreamPolicy sample_period must be positive, not 0")
        start = _time(start_time, "start_time")
        end = _time(end_time, "end_time")
        if start is not None and end is not None and end < start:
            raise DkError(f"StreamPolicy end_time {end} is before start_time {start}")
        flags = {
            "ordered_on_valid_time": ordered_on_valid_time,
            "unique_valid_time": unique_valid_time,
            "span_from_first": span_from_first,
        }
        for name, flag in flags.items():
            if not isinstance(flag, bool):
                raise DkError(f"StreamPolicy {name} must be True or False, not {flag!r}")
        fields = {
            "sample_period": period,
            "sample_period_deviation": duration(
                sample_period_deviation, "StreamPolicy sample_period_deviation"
            ),
            "approximation": approximation,
            "max_age": _optional(max_age, "max_age"),
            "delay_before_approximation": duration(
                delay_before_approximation, "StreamPolicy delay_before_approximation"
            ),
            "start_time": start,
            "end_time": end,
            "max_delay": _optional(max_delay, "max_delay"),
            **flags,
            "end_of_data": end_of_data,
        }
        for name, value in fields.items():
            object.__setattr__(self, name, value)


def _optional(value: Seconds | None, name: str) -> Fraction | None:
    return None if value is None else duration(value, f"StreamPolicy {name}")


def _time(value: Seconds | None, name: str) -> Fraction | None:
    """A time on the stream's clock (or from its first sample): it may be negative."""
    if value is None:
        return None
    if isinstance(value, str):
        sign = -1 if value.strip().startswith("-") else 1
        return sign * duration(value.strip().lstrip("-"), f"StreamPolicy {name}")
    return exact(value, f"StreamPolicy {name}")


DEFAULT = StreamPolicy()
