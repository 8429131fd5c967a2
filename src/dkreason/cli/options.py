"""What the monitoring options mean, for every mode (recordings, --live, --ros2): the
formulas given and the stream policy, whose defaults are StreamPolicy's own."""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import DkError
from ..parse.formula import read_formulas
from ..stream.policy import StreamPolicy


def formulas(args: argparse.Namespace) -> list[str]:
    """The formulas given, then those of each -f file."""
    out = [*args.formulas, *(f for path in args.formulas_file for f in read_formulas(path))]
    if not out:
        raise DkError("no formula given (as arguments or with -f FILE)")
    return out


def policy(args: argparse.Namespace) -> StreamPolicy:
    """The stream policy the options give; an option not given keeps StreamPolicy's default,
    the one the API has."""
    given: dict[str, Any] = {
        "sample_period": args.period,
        "sample_period_deviation": args.deviation,
        "approximation": args.approximation,
        "max_age": args.max_age,
        "delay_before_approximation": args.delay,
        "start_time": args.start,
        "end_time": args.end,
        "max_delay": args.max_delay,
        "end_of_data": args.end_of_data,
        "set_aside_after": args.set_aside_after,
    }
    chosen = {k: v for k, v in given.items() if v is not None}
    if chosen.get("max_age") == "inf":
        chosen["max_age"] = None
    return StreamPolicy(
        **chosen,
        ordered_on_valid_time=args.ordered,
        unique_valid_time=args.unique,
        best_source=args.best_source,
    )
