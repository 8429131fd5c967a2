"""What a person reads: events, the stream request, the summary table, the exit status.

One table of verdict words serves every command and the plot."""

from __future__ import annotations

import datetime
import json
import sys
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from ..model import StreamRequest, TopicMatch, ros_name
from ..monitor import WORDS, Event, Rerouted
from ..names import local_name
from ..progress import InstanceVerdict, Verdict
from ..stream.units import since

if TYPE_CHECKING:  # the knowledge base's modules load only when a command needs them
    from ..policy.check import Diagnostic
    from ..query import Answer, Cell, RelationInfo

NAMED = 10  # objects named per status in a verdict's text; the rest are counted


def exit_status(verdicts: list[bool | None], failed_constraint: bool = False) -> int:
    """0: every formula held; 1: one was violated, or `failed_constraint` (a stream
    constraint was, under --fail-on-constraint); 3: none violated, one left unknown."""
    if False in verdicts or failed_constraint:
        return 1
    return 0 if all(verdicts) else 3


def shout(verdict: bool | None) -> str:
    """A verdict's word in an event line: a violation stands out."""
    word = WORDS[verdict]
    return word.upper() if verdict is False else word


def event(event: Event, as_json: bool) -> None:
    """A verdict, violation or re-route; times as `t+…` from the start of the recording
    (and, on an epoch clock, as ISO 8601 UTC)."""
    out = event.to_json()
    if as_json:
        print(json.dumps(out, ensure_ascii=False, default=str), flush=True)
        return
    when = _when(out.get("time"), event.t)
    if isinstance(event, Rerouted):
        print(f"rerouted at {when}: {event}", flush=True)
    elif isinstance(event, Verdict):
        if event.update:  # the same verdict: more of its instances settled
            lines = [f"update (still {shout(event.verdict)}): {event.formula}"]
        else:
            said = "at end" if event.at_end else f"at {when}"
            lines = [f"{said}: {shout(event.verdict)}  {event.formula}"]
            if event.witness:
                lines.append(event.witness)
            if event.robustness is not None:
                lines.append(f"robustness: {event.robustness.text()}")
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


def _when(time: Any, t: Any) -> str:
    """`t+…` with the time on the recording's clock; one reading where they are the same."""
    if time is None or t is None or t == time:
        return f"{time} s"
    stamp = f"{time} s"
    if time > 10**9:  # an epoch clock: the date says more than a ten-digit number
        stamp = (
            datetime.datetime.fromtimestamp(time, datetime.UTC)
            .isoformat(timespec="milliseconds")
            .replace("+00:00", "Z")
        )
    return f"{since(t)} ({stamp})"


def summary(verdicts: list[Verdict], violations: Counter[str]) -> None:
    """The verdicts as a table (times as `t`, from the start of the recording), and the
    stream constraint violations counted per kind."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title="dkreason monitor", title_justify="left")
    for column in ("formula", "verdict", "t (s)", "at end"):
        table.add_column(column)
    for v in verdicts:
        if v.update:  # the same verdict, said again
            continue
        t = "–" if v.t is None else str(v.t)  # never decided: no time
        table.add_row(escape(v.formula), WORDS[v.verdict], t, "yes" if v.at_end else "no")
    console = Console(width=120)
    console.print(table)
    console.print(constraint_counts(violations))


def constraint_counts(violations: Counter[str]) -> str:
    """The stream constraint violations per kind, most first, in one line."""
    counts = ", ".join(f"{n} {kind}" for kind, n in violations.most_common())
    return f"stream constraint violations: {counts or 'none'}"


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
    """Thesis listings 6.2–6.4 and 6.8–6.10, plus where remote topics come from; a topic of a
    platform with a namespace by the ROS name it resolves to (`/turtle1/pose`)."""
    namespaces = dict(request.namespaces)
    heading = "Read from:" if request.best_source else "Topics to merge:"
    lines = []
    for f in request.features:
        lines += [
            f"Feature: {f.feature.key}",
            heading if f.topics else f"{heading} none",
        ]
        lines += [_topic(t, request.local, namespaces) for t in f.topics]
        if f.standby:  # --best-source: read too, to re-route to when the first one stops
            lines.append("Standing by:")
            lines += [_topic(t, request.local, namespaces) for t in f.standby]
    lines += [f"Warning: {w}" for w in request.warnings]
    return "\n".join(lines)


def _topic(t: TopicMatch, local: str, namespaces: dict[str, str]) -> str:
    ids = "".join(f"Id: {k} = {v}, " for k, v in t.filter)
    where = (
        ""
        if t.platform == local
        else f" (platform {t.platform}, as {t.as_feature}[{', '.join(t.as_args)}])"
    )
    namespace = namespaces.get(t.platform)
    name = t.topic if namespace is None else ros_name(t.topic, namespace)
    return f"  Topic: {name}{where}, Message type: {t.msgtype}, {ids}Field: {t.field}"


def formula_warnings(found: Sequence[str], as_json: bool) -> None:
    """Warnings (what formulas probably do not mean, `X != X`; with a request, all of its):
    JSON lines `{"warning": …}` before the verdicts, or lines on stderr."""
    for w in found:
        if as_json:
            print(json.dumps({"warning": w}, ensure_ascii=False), flush=True)
        else:
            print(f"warning: {w}", file=sys.stderr)


def warnings(found: list[Diagnostic]) -> None:
    """The rule files' warnings, on stderr: they do not stop a run."""
    for d in found:
        print(f"warning: {d}", file=sys.stderr)


def _cell(value: Cell) -> str:
    if isinstance(value, tuple):
        return f"({', '.join(map(_cell, value))})"
    if value == "":
        return "–"
    return local_name(value) if isinstance(value, str) and "://" in value else str(value)


def _table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(x) for x in column) for column in zip(header, *rows, strict=True)]
    return "\n".join(
        "  ".join(x.ljust(w) for x, w in zip(row, widths, strict=True)).rstrip()
        for row in (header, *rows)
    )


def answer(a: Answer) -> str:
    """A query's answer as a table, IRIs by their local names ('' as –); no variable: yes or
    no."""
    if not a.columns:
        return "yes" if a.rows else "no"
    if not a.rows:
        return "(no answer)"
    return _table(list(a.columns), [[_cell(v) for v in row] for row in a.rows])


def relations(found: list[RelationInfo]) -> str:
    """`dkreason query --relations`: each relation with its columns, kind and rows."""
    return _table(
        ["relation", "kind", "rows"],
        [
            [
                f"{r.relation.name}({', '.join(r.relation.columns)})",
                r.relation.kind or "derived",
                str(r.rows) if r.rows is not None else f"– ({r.note})",
            ]
            for r in found
        ],
    )
