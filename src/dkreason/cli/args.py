"""Argument parsing shared by the commands: one-line errors, value types, option groups.

Values are checked here (an argparse type's error is its one line, exit 2); what they mean is
the façade's: a duration is read as `StreamPolicy` reads it, so the CLI and the API agree."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any, Literal, NoReturn

from ..errors import DkError, one_line
from ..inputs.numbers import duration
from ..stream import TYPESTORES
from ..stream.policy import time_bound


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, like every other input error
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


RECORDING_SUFFIXES = (".bag", ".mcap", ".db3", ".jsonl")


def _recording(token: str) -> bool:
    """A `[PLATFORM=]PATH` that names a recording (a file or a ROS 2 bag folder)."""
    path = Path(token if Path(token).exists() else token.partition("=")[2] or token)
    return path.suffix in RECORDING_SUFFIXES or (path / "metadata.yaml").is_file()


def _formulas_file(token: str) -> bool:
    return Path(token).is_file() and not _recording(token)


def _topic(token: str) -> bool:
    return token.startswith("/") and not Path(token).exists()


# The options taking a list of files (or topics), and what a further value looks like: an
# option given several values, as a shell glob gives them (`--msg msg/*.msg`), takes those
# that look like its values; the next that does not is the next argument (a formula, DIR).
LISTS: dict[str, Callable[[str], bool]] = {
    "--msg": lambda t: t.endswith(".msg"),
    "--source": _recording,
    "-f": _formulas_file,
    "--formulas-file": _formulas_file,
    "--topics": _topic,
}
SPREAD = (
    "monitor",
    "info",
    "init",
    "batch",
    "plot",
)  # the commands whose list options take several


def spread(argv: Sequence[str]) -> list[str]:
    """`--msg A B` read as `--msg A --msg B` (see LISTS), in the commands of SPREAD."""
    args = list(argv)
    if not args or args[0] not in SPREAD:
        return args
    out: list[str] = []
    option: str | None = None
    i = 0
    while i < len(args):
        token = args[i]
        if token == "--":
            return out + args[i:]
        if option is not None and not token.startswith("-") and LISTS[option](token):
            out += [option, token]
            i += 1
            continue
        name, eq, _ = token.partition("=")
        option = name if name in LISTS and token.startswith("-") else None
        out.append(token)
        i += 1
        if option is not None and not eq and i < len(args):  # its own first value, as it is
            out.append(args[i])
            i += 1
    return out


Sub = Any  # argparse's subparsers action (its class is private)
Options = Any  # a parser or an argument group (its class is private)


def seconds(text: str) -> Fraction:
    """A duration as formulas write it: seconds, or a number with ms, s, min or h."""
    try:
        return duration(text, "seconds")
    except DkError:
        if text.strip().startswith("-"):
            raise argparse.ArgumentTypeError(f"must not be negative: {text}") from None
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a duration (like 5, 0.1, 500ms, 2min)"
        ) from None


def seconds_or_inf(text: str) -> Fraction | Literal["inf"]:
    return "inf" if text in ("inf", "oo") else seconds(text)


def bound(text: str) -> str:
    """A start or end time as StreamPolicy reads it (checked here, meant there): +SECONDS
    after the recording's start, seconds on its clock, or an ISO 8601 time."""
    try:
        time_bound(text, "time")
    except DkError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


LARGEST = 1e9  # a wait, duration or speed factor: 31 years, within what a timer holds
LATEST = 1e10  # a Unix time (s): the year 2286, within what a clock of int64 ns holds


def finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text}")
    return value


def positive(text: str) -> float:
    """A wait, duration or factor: positive and at most LARGEST (a timer given 1e300 s
    overflows)."""
    value = finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive: {text}")
    if value > LARGEST:
        raise argparse.ArgumentTypeError(f"must be at most {LARGEST:g}: {text}")
    return value


def wall_time(text: str) -> float:
    """A Unix time in seconds, from 0 to LATEST (a replay's clock at 1e300 overflows)."""
    value = finite(text)
    if not 0 <= value <= LATEST:
        raise argparse.ArgumentTypeError(f"expected a Unix time from 0 to {LATEST:g} s: {text}")
    return value


def speed(text: str) -> float:
    """A replay speed: 1 real time, 0 as fast as it reads."""
    value = finite(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected 0 or more (1: real time), got {text}")
    return value


def whole(text: str) -> int:
    """A count of at least 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return int(text)


def count(text: str) -> int:
    """A count, 0 or more."""
    if not text.isdigit():
        raise argparse.ArgumentTypeError(f"expected a whole number, 0 or more, got {text!r}")
    return int(text)


def domain(text: str) -> int:
    """A ROS_DOMAIN_ID: 0 to 232 (an argparse type, so a ValueError is its one-line error)."""
    if not text.isdigit() or int(text) > 232:
        raise argparse.ArgumentTypeError(f"ROS domain id {text!r}: expected 0 to 232")
    return int(text)


def ros_domain(given: int | None) -> int:
    """--domain, else $ROS_DOMAIN_ID, else 0."""
    if given is not None:
        return given
    try:
        return domain(os.environ.get("ROS_DOMAIN_ID", "0") or "0")
    except argparse.ArgumentTypeError as exc:
        raise DkError(f"$ROS_DOMAIN_ID: {exc}") from None


def config(p: argparse.ArgumentParser, required: bool = True) -> None:
    p.add_argument(
        "--config",
        required=required,
        type=Path,
        help="TOML config file" if required else "TOML config file (optional)",
    )


def formulas_file(p: Options) -> None:
    """-f FILE, for the commands that monitor."""
    p.add_argument(
        "-f",
        "--formulas-file",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="formulas, one per line (# comments); several: -f A B, or repeated",
    )


def definitions(p: Options) -> None:
    p.add_argument(
        "--msg",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="a pkg/msg/Name.msg definition, for recordings that store none or to "
        "replace a wrong one they store (several: --msg msg/*.msg, or repeated)",
    )
    p.add_argument(
        "--typestore",
        choices=TYPESTORES,
        help="rosbags' standard message definitions for recordings that store "
        "none (default ros1_noetic for .bag, else ros2_humble)",
    )


def network(p: Options) -> None:
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to, e.g. tcp/10.0.0.2:7447 (repeatable)",
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)",
    )
    p.add_argument(
        "--zenoh-config",
        metavar="FILE",
        help="Zenoh config file (TLS, access control); endpoints still apply",
    )
