"""`StreamPolicy`: how samples become states (thesis listing 5.2's constraints plus the
approximation), checked when it is made and defined once for the CLI and the API alike.

Durations and times are seconds: numbers (exact as written: 0.1 is 1/10) or text with a unit
(`"500ms"`, `"2 min"`), the same as `dkreason monitor` takes them.  The start and end times
bound what is judged: seconds on the recording's clock, an ISO 8601 time
(`"2014-03-31T19:24:50Z"`), or `"+SECONDS"` after the start of the recording (its first record,
of any topic, where `t` counts from).
"""

from __future__ import annotations

import datetime
import re
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
    span_from_start: bool  # start_time and end_time count from the start of the recording
    # at the end of the data, a bounded window reaching past it stays undecided ("open"), or
    # closes as on a finite trace ("finite", the thesis' semantics)
    end_of_data: Literal["open", "finite"]
    # each feature read from its best-ranked topic only (the policy's rank: by declared
    # quality), not from the merge of every relevant topic (the thesis')
    best_source: bool
    # a topic declaring a rate whose samples stop for more than this many declared periods
    # is set aside (its features matched again without it) until it sends again; 0: never
    set_aside_after: int

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
        span_from_start: bool = False,
        end_of_data: Literal["open", "finite"] = "open",
        best_source: bool = False,
        set_aside_after: int = 3,
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
        if type(set_aside_after) is not int or set_aside_after < 0:
            raise DkError(
                f"StreamPolicy set_aside_after must be a whole number of periods, 0 or more, "
                f"not {set_aside_after!r}"
            )
        period = _optional(sample_period, "sample_period")
        if period == 0:
            raise DkError("StreamPolicy sample_period must be positive, not 0")
        flags = {
            "ordered_on_valid_time": ordered_on_valid_time,
            "unique_valid_time": unique_valid_time,
            "span_from_start": span_from_start,
            "best_source": best_source,
        }
        for name, flag in flags.items():
            if not isinstance(flag, bool):
                raise DkError(f"StreamPolicy {name} must be True or False, not {flag!r}")
        raw = {"start_time": start_time, "end_time": end_time}
        bounds = {
            name: time_bound(value, f"StreamPolicy {name}")
            for name, value in raw.items()
            if value is not None
        }
        kinds = {kind for _, kind in bounds.values()}
        if "iso" in kinds if span_from_start else "relative" in kinds and len(kinds) > 1:
            shown = ", ".join(f"{name} {raw[name]!r}" for name in bounds)
            raise DkError(
                f"StreamPolicy {shown}: must be both relative (+SECONDS) or both absolute "
                "(an ISO 8601 time is absolute)"
            )
        flags["span_from_start"] = span_from_start or "relative" in kinds
        start, end = (bounds[name][0] if name in bounds else None for name in raw)
        if start is not None and end is not None and end < start:
            raise DkError(f"StreamPolicy end_time {end} is before start_time {start}")
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
            "set_aside_after": set_aside_after,
        }
        for name, value in fields.items():
            object.__setattr__(self, name, value)


def _optional(value: Seconds | None, name: str) -> Fraction | None:
    return None if value is None else duration(value, f"StreamPolicy {name}")


BoundKind = Literal["absolute", "relative", "iso"]
_ISO = re.compile(r"(\d{4}-\d\d-\d\d[T ]\d\d:\d\d(?::\d\d(\.\d+)?)?)(Z|[+-]\d\d:?\d\d)?", re.I)
_EPOCH = datetime.datetime(1970, 1, 1, tzinfo=datetime.UTC)


def time_bound(value: Seconds, what: str) -> tuple[Fraction, BoundKind]:
    """A start or end time, exact: seconds on the stream's clock (they may be negative), an
    ISO 8601 time with its zone (as epoch seconds, to the digit written), or `+SECONDS` after
    the start of the recording."""
    if not isinstance(value, str):
        return exact(value, what), "absolute"
    text = value.strip()
    if text.startswith("+"):
        return duration(text[1:], what), "relative"
    iso = _ISO.fullmatch(text)
    if iso is None:
        sign = -1 if text.startswith("-") else 1
        return sign * duration(text.lstrip("-"), what), "absolute"
    moment, fraction, zone = iso.groups()
    if zone is None:
        raise DkError(f"{what} {text!r} has no time zone: add Z for UTC, or an offset like +02:00")
    whole = moment.removesuffix(fraction or "")
    try:
        when = datetime.datetime.fromisoformat(whole + ("+00:00" if zone in "zZ" else zone))
    except ValueError as exc:
        raise DkError(f"{what} {text!r} is not an ISO 8601 time ({exc})") from None
    seconds = (when - _EPOCH) // datetime.timedelta(seconds=1)
    return seconds + Fraction("0" + (fraction or "")), "iso"


DEFAULT = StreamPolicy()
