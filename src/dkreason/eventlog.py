"""Monitoring events as Foxglove's Log panel reads them (`foxglove.Log`, JSON encoding), for
`--record`, `--clips` and `--foxglove`: one line per verdict (name: the formula; message:
the witness; timestamp: when it was decided), per instance of a quantified formula as it
settles, per stream constraint violation and per federation change; the level says the kind
(a violation an error, an unknown verdict or a constraint broken a warning)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .monitor import WORDS
from .progress import InstanceVerdict, Verdict
from .stream.processor import Violation
from .stream.units import NS

INFO, WARNING, ERROR = 2, 3, 4
LEVEL: dict[bool | None, int] = {True: INFO, False: ERROR, None: WARNING}
LOG_TOPIC = "/dkreason/log"
LOG_SCHEMA: dict[str, Any] = {
    "title": "foxglove.Log",
    "description": "A log message",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "level": {"title": "foxglove.LogLevel", "type": "integer", "minimum": 0, "maximum": 5},
        "message": {"type": "string"},
        "name": {"type": "string"},
        "file": {"type": "string"},
        "line": {"type": "integer", "minimum": 0},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}
"""`foxglove.Log`'s JSON schema (foxglove-sdk's, its descriptions left out), the channel's."""


def ns(seconds: Any, default: int) -> int:
    """A time in seconds on the stream clock as ns (`default` when there is none)."""
    return default if seconds is None else round(seconds * NS)


def log(at: int, level: int, name: str, message: str) -> dict[str, Any]:
    """One `foxglove.Log` message at `at` ns (a time before 1970 is said at 0)."""
    at = max(at, 0)
    return {
        "timestamp": {"sec": at // NS, "nsec": at % NS},
        "level": level,
        "message": message,
        "name": name,
        "file": "",
        "line": 0,
    }


@dataclass
class EventLog:
    """What a run has said so far, so an instance is logged once, when it settles."""

    said: set[tuple[str, tuple[tuple[str, str], ...]]] = field(default_factory=set)

    def lines(self, event: Any, at: int) -> list[tuple[int, dict[str, Any]]]:
        """`event`'s log lines and their times (ns); `at`: the time of an event without one
        (a verdict no state decided, a change before the clock)."""
        if isinstance(event, Verdict):
            out = []
            if not event.update:
                when = ns(event.time, at)
                text = event.witness or f"{WORDS[event.verdict]} at {_t(event.t)}"
                if event.robustness is not None:  # --robustness: by how much, and from where
                    text += f"\nrobustness: {event.robustness.text()}"
                out.append((when, log(when, LEVEL[event.verdict], event.formula, text)))
            for i in event.instances or ():
                if i.status != "open" and (event.formula, i.bindings) not in self.said:
                    self.said.add((event.formula, i.bindings))
                    out.append(self._instance(event.formula, i, at))
            return out
        if isinstance(event, Violation):
            when = ns(event.time, at)
            text = f"{event.feature} on {event.topic}: {event.detail}"
            return [(when, log(when, WARNING, f"stream constraint {event.constraint}", text))]
        when = ns(getattr(event, "time", None), at)  # a federation change
        return [(when, log(when, INFO, "dkreason", str(event)))]

    @staticmethod
    def _instance(formula: str, i: InstanceVerdict, at: int) -> tuple[int, dict[str, Any]]:
        when = ns(i.time, at)
        text = i.witness or f"{i.status} at {_t(i.t)}"
        return when, log(when, LEVEL[i.verdict], f"{formula} [{i.name}]", text)


def _t(t: Any) -> str:
    return "the end" if t is None else f"t+{t} s"
