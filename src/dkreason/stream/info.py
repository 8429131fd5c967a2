"""What recordings hold, and which spec topics they bind: `dkreason info`.

Per recording: each topic with its message type and count, the time span and the clock of
its header stamps, and what is damaged.  Counts and span are what the recording holds: an
indexed MCAP file's chunks are read (a damaged chunk is named, with what of it was read);
a file without a usable index is read through; only a ROS 1 bag's or an sqlite3 file's
index is taken at its word.  With a knowledge base: every spec topic of every platform, and
the recording topic it binds to (stream/binding.py), or that none does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..model import TopicMatch
from .binding import Recording, Recordings, message_type_fits, recording_names
from .damaged import DamagedRecording
from .units import NS, seconds_text


@dataclass(frozen=True, slots=True)
class TopicInfo:
    name: str
    msgtype: str
    count: int | None


@dataclass(frozen=True, slots=True)
class RecordingInfo:
    name: str
    topics: tuple[TopicInfo, ...]
    start: int | None  # ns, record time
    end: int | None
    clock: str  # header, record (stamps on another clock), or none (nothing stamped)
    damage: tuple[str, ...] = ()  # what could not be read, a line each

    def to_json(self) -> dict[str, Any]:
        return {
            "recording": self.name,
            "clock": self.clock,
            "start": None if self.start is None else round(self.start / NS, 9),
            "end": None if self.end is None else round(self.end / NS, 9),
            "topics": [{"topic": t.name, "type": t.msgtype, "count": t.count} for t in self.topics],
            "damage": list(self.damage),
        }


@dataclass(frozen=True, slots=True)
class Binding:
    platform: str
    topic: str
    msgtype: str
    bound: str | None  # the recording topic, None when no recording holds it
    recorded_type: str | None

    def to_json(self) -> dict[str, Any]:
        return {
            "platform": self.platform,
            "topic": self.topic,
            "msgtype": self.msgtype,
            "recording_topic": self.bound,
            "recorded_type": self.recorded_type,
        }


def describe(recording: Recording) -> RecordingInfo:
    """A recording's topics, counts, span, clock and damage (see the module docstring)."""
    source = recording.source
    types = source.types()
    counts: dict[str, int] = {}
    start = end = None
    damage: tuple[str, ...] = ()
    reader = getattr(source, "reader", None)
    survey = getattr(source, "survey", lambda: None)()
    if survey is not None:
        counts, start, end = survey.counts, survey.start, survey.end
        damage = tuple(str(d) for d in survey.damaged)
    elif types and reader is not None:
        if reader.message_count:  # else rosbags' start is 2**63 - 1, its end 0
            start, end = reader.start_time, reader.end_time
        counts = {t: source.count({t}) or 0 for t in types}
    else:  # read through: topics, counts and span as they come
        found: dict[str, str] = {}
        try:
            for topic, available, _, _ in _every(source):
                found.setdefault(topic, types.get(topic, "(JSON)"))
                counts[topic] = counts.get(topic, 0) + 1
                start = available if start is None else min(start, available)
                end = available if end is None else max(end, available)
        except DamagedRecording as exc:
            damage = (str(exc).removeprefix(f"{source.name}: "),)
        types = types or found
    clock = Recordings([recording], clock="auto")
    return RecordingInfo(
        source.name,
        tuple(TopicInfo(t, types[t], counts.get(t, 0)) for t in sorted(types)),
        start,
        end,
        clock.clock if clock.stamped else "none",
        damage,
    )


def _every(source: Any) -> Any:
    records = getattr(source, "records", None)
    return records() if records is not None else source.messages({t: [] for t in source.types()})


def bindings(kb: Any, recordings: Recordings) -> list[Binding]:
    """Every spec topic of every platform, and the recording topic that carries it."""
    types = recordings.types()
    namespaces = {p.name: p.namespace for p in (kb.config.platforms if kb.config else ())}
    shared = kb.shared_names()
    out = []
    for name, platform in kb.platforms.items():
        for spec in platform.specs.values():
            m = TopicMatch(name, spec.name, spec.msgtype, "", (), "", ())
            names = recording_names(m, kb.local, namespaces.get(name), shared)
            found = next((n for n in names if n in types), None)
            out.append(
                Binding(
                    name, spec.name, spec.msgtype, found, None if found is None else types[found]
                )
            )
    return out


def render(infos: Sequence[RecordingInfo], binds: Sequence[Binding] | None) -> str:
    lines = []
    for info in infos:
        span = (
            ""
            if info.start is None or info.end is None
            else f", {seconds_text(info.end - info.start)} s from {seconds_text(info.start)}"
        )
        lines.append(
            f"{info.name}: {len(info.topics)} topic(s){span}; header stamps: "
            + {
                "header": "on the record clock",
                "record": "on another clock (simulated time?): the record time is used",
                "none": "none",
            }[info.clock]
        )
        width = max((len(t.name) for t in info.topics), default=0)
        lines += [
            f"  {t.name:<{width}}  {t.msgtype}  {t.count if t.count is not None else '?'}"
            for t in info.topics
        ]
        lines += [f"  damaged: {d}" for d in info.damage]
    for b in binds or ():
        where = f"{b.platform}/{b.topic} ({b.msgtype})"
        if b.bound is None:
            lines.append(f"{where}: in no recording")
        elif b.recorded_type is not None and not message_type_fits(b.recorded_type, b.msgtype):
            lines.append(f"{where}: {b.bound} carries {b.recorded_type}, not {b.msgtype}")
        else:
            lines.append(f"{where} ← {b.bound}")
    return "\n".join(lines)
