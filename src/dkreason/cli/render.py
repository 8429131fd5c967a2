"""What a person reads: events, the stream request, the summary table, the exit status.

One table of verdict words serves every command and the plot."""

from __future__ import annotations

import datetime
import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from decimal import Decimal
from fractions import Fraction
from typing import Any

from ..model import StreamRequest
from ..monitor import WORDS, Event
from ..progress import InstanceVerdict, Verdict

NAMED = 10  # objects named per status in a verdict's text; the rest are counted


def exit_status(verdicts: list[bool | None]) -> int:
    """0: every formula held; 1: one was violated; 3: none violated, one left unknown."""
    if False in verdicts:
        return 1
    return 0 if all(verdicts) else 3


def shout(verdict: bool | None) -> str:
    """A verdict's word in an event line: a violation stands out."""
    word = WORDS[verdict]
    return word.upper() if verdict is False else word


def event(event: Event, as_json: bool, start: Fraction | None = None) -> None:
    """A verdict or violation; with the recording's first time (s), times also as `t+…`
    since then (and, on an epoch clock, as ISO 8601 UTC)."""
    out = event.to_json()
    if as_json:
        if start is not None:
            for said in (out, *out.get("instances", ())):
                if said.get("time") is not None:
                    said["t"] = _since(said["time"], start)
        print(json.dumps(out, ensure_ascii=False, default=str), flush=True)
        return
    when = _when(out.get("time"), start)
    if isinstance(event, Verdict):
        if event.update:  # the same verdict: more of its instances settled
            lines = [f"update (still {shout(event.verdict)}): {event.formula}"]
        else:
            said = "at end" if event.at_end else f"at {when}"
            lines = [f"{said}: {shout(event.verdict)}  {event.formula}"]
            if event.witness:
                lines.append(event.witness)
        if event.pending and event.witness is None:
            lines.append(f"pending: {event.pending}")
        if event.instances is not None:
            lines += _instances(event)
        print("\n    ".join(lines), flush=True)
    else:
        print(
            f"violation at {when}: {event.constraint} on {event.feature} ({event.topic}): "
            f"{event.detail}",
            flush=True,
        )


def _instances(v: Verdict) -> list[str]:
    """Which objects violated, held, stayed unknown, were never observed or are still open;
    in an update, also why each instance that violated after the verdict did."""
    by: dict[str, list[InstanceVerdict]] = {}
    for i in v.instances or ():
        by.setdefault(i.status, []).append(i)
    said = []
    for status in ("violated", "held", "unknown", "never observed", "open"):
        them = by.get(status, [])
        if them:
            names = [i.name for i in them[:NAMED]]
            more = f" and {len(them) - NAMED} more" if len(them) > NAMED else ""
            said.append(f"{status} {', '.join(names)}{more}")
    lines = [f"instances: {'; '.join(said)}"]
    if v.update:
        later = [i for i in by.get("violated", []) if i.time != v.time]
        lines += [f"{i.name} {i.witness}" for i in later[:NAMED]]
        if len(later) > NAMED:
            lines.append(f"and {len(later) - NAMED} more violations")
    return lines


def _when(time: Any, start: Fraction | None) -> str:
    if time is None or not start:  # a clock that starts at 0 needs no second reading
        return f"{time} s"
    stamp = f"{time} s"
    if time > 10**9:  # an epoch clock: the date says more than a ten-digit number
        stamp = (
            datetime.datetime.fromtimestamp(time, datetime.UTC)
            .isoformat(timespec="milliseconds")
            .replace("+00:00", "Z")
        )
    return f"t+{_since(time, start)} s ({stamp})"


def _since(time: float, start: Fraction) -> float:
    """Seconds from `start` to `time` (s, as printed), exact to the nanosecond."""
    return float(Decimal(repr(time)) - Decimal(start.numerator) / Decimal(start.denominator))


def summary(verdicts: list[Verdict], violations: int) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title="dkreason monitor", title_justify="left")
    for column in ("formula", "verdict", "time (s)", "at end"):
        table.add_column(column)
    for v in verdicts:
        if v.update:  # the same verdict, said again
            continue
        table.add_row(escape(v.formula), WORDS[v.verdict], str(v.time), "yes" if v.at_end else "no")
    console = Console(width=120)
    console.print(table)
    console.print(f"{violations} stream constraint violation(s)")


@contextmanager
def progress_bar(total: int | None, enabled: bool) -> Iterator[Callable[[int], None] | None]:
    """A progress bar on stderr while a long file is read (only on a terminal)."""
    if not (enabled and sys.stderr.isatty()):
        yield None
        return
    from rich.progress import Progress

    with Progress(transient=True) as bar:
        task = bar.add_task("reading", total=total)
        yield lambda n: bar.update(task, completed=n)


def request(request: StreamRequest) -> str:
    """Thesis listings 6.2–6.4 and 6.8–6.10, plus where remote topics come from."""
    lines = []
    for f in request.features:
        lines += [
            f"Feature: {f.feature.key}",
            "Topics to merge:" if f.topics else "Topics to merge: none",
        ]
        for t in f.topics:
            ids = "".join(f"Id: {k} = {v}, " for k, v in t.filter)
            where = (
                ""
                if t.platform == request.local
                else f" (platform {t.platform}, as {t.as_feature}[{', '.join(t.as_args)}])"
            )
            lines.append(
                f"  Topic: {t.topic}{where}, Message type: {t.msgtype}, {ids}Field: {t.field}"
            )
    lines += [f"Warning: {w}" for w in request.warnings]
    return "\n".join(lines)
