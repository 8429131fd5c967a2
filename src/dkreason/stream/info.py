"""What recordings hold, and which spec topics they bind: `dkreason info`.

Per recording: each topic with its message type and count, the time span and the clock of
its header stamps, and what is damaged.  Counts and span are what the recording holds: an
indexed MCAP file's chunks are read (a damaged chunk is named, with what of it was read);
a file without a usable index is read through; only a ROS 1 bag's or an sqlite3 file's
index is taken at its word.  With `fields`: each topic's field paths a spec can read, with
their types (fields.py).  With a knowledge base: every spec topic of every platform, and the
recording topic it binds to (stream/binding.py), or that none does.  A folder holding several
recordings is read as those recordings.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

from ..model import TopicMatch, stream_name
from ..parse.sslt import format_quality
from .binding import (
    Recording,
    Recordings,
    expand_folders,
    message_type_fits,
    open_recordings,
    recording_names,
)
from .damaged import DamagedRecording
from .fields import FieldPath, paths
from .quality import Timing, observe
from .units import NS, seconds_text


@dataclass(frozen=True, slots=True)
class Gap:
    """A topic's longest time without a message (a dropout the median rate hides): its length
    and the record time it starts at (ns)."""

    length: int  # ns
    start: int

    def to_json(self) -> dict[str, Any]:
        return {"seconds": round(self.length / NS, 9), "from": round(self.start / NS, 9)}


@dataclass(frozen=True, slots=True)
class TopicInfo:
    name: str
    msgtype: str
    count: int | None
    fields: tuple[FieldPath, ...] = ()  # when asked for, and the definition is known
    timing: Timing | None = None  # observed rate and delay, when asked for
    gap: Gap | None = None  # with the timing, of two messages or more

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"topic": self.name, "type": self.msgtype, "count": self.count}
        out |= {"fields": [f.to_json() for f in self.fields]} if self.fields else {}
        out |= {"longest_gap": self.gap.to_json()} if self.gap else {}
        return out | (self.timing.to_json() if self.timing else {})


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
            "topics": [t.to_json() for t in self.topics],
            "damage": list(self.damage),
        }


@dataclass(frozen=True, slots=True)
class Binding:
    platform: str
    topic: str
    msgtype: str
    bound: str | None  # the recording topic, None when no recording holds it
    recorded_type: str | None
    rate: Fraction | None = None  # as the spec declares them (Hz, s)
    delay: Fraction | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "platform": self.platform,
            "topic": self.topic,
            "msgtype": self.msgtype,
            "recording_topic": self.bound,
            "recorded_type": self.recorded_type,
        }
        declared = {"rate": self.rate, "delay": self.delay}
        return out | {k: float(v) for k, v in declared.items() if v is not None}


def inspect(
    given: Sequence[str | Path],
    kb: Any = None,
    *,
    fields: bool = False,
    msg: Sequence[Path] = (),
    typestore: str | None = None,
    timing: bool = False,
) -> tuple[list[RecordingInfo], list[Binding] | None]:
    """What `dkreason info` shows: each recording described (a folder of several, each of
    them), and with a knowledge base the spec topics' bindings."""
    recordings = open_recordings(
        expand_folders(given),
        kb.platforms if kb is not None else (),
        clock="header",  # each recording's own clock: describe() says which
        msg=msg,
        typestore=typestore,
    )
    try:
        infos = [describe(r, fields, timing) for r in recordings.parts]
        return infos, bindings(kb, recordings) if kb is not None else None
    finally:
        recordings.close()


def describe(recording: Recording, fields: bool = False, timing: bool = False) -> RecordingInfo:
    """A recording's topics, counts, span, clock and damage (see the module docstring); with
    `timing`, each topic's observed rate and delay (every message read)."""
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
    fielddefs = getattr(getattr(source, "store", None), "fielddefs", {}) if fields else {}
    timings, gaps = _timings(source, clock.clock == "header") if timing and not damage else ({}, {})
    return RecordingInfo(
        source.name,
        tuple(
            TopicInfo(
                t,
                types[t],
                counts.get(t, 0),
                tuple(paths(fielddefs, types[t])),
                timings.get(t),
                gaps.get(t),
            )
            for t in sorted(types)
        ),
        start,
        end,
        clock.clock if clock.stamped else "none",
        damage,
    )


def _timings(source: Any, stamped: bool) -> tuple[dict[str, Timing], dict[str, Gap]]:
    """Each topic's observed rate, and its delay where its header stamps are on the record
    clock (`stamped`) and a message's stamp differs from its record time; its longest gap."""
    arrivals: dict[str, list[int]] = {}
    lags: dict[str, list[int]] = {}
    for topic, available, valid, _ in source.messages({t: [] for t in source.types()}):
        arrivals.setdefault(topic, []).append(available)
        lags.setdefault(topic, []).append(available - valid)
    timings = {
        t: observe(times, lags[t] if stamped and any(lags[t]) else None)
        for t, times in arrivals.items()
    }
    gaps = {
        t: max((Gap(b - a, a) for a, b in zip(times, times[1:], strict=False)), key=_length)
        for t, times in arrivals.items()
        if len(times) > 1
    }
    return timings, gaps


def _length(gap: Gap) -> int:
    return gap.length


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
            recorded = None if found is None else types[found]
            out.append(
                Binding(name, spec.name, spec.msgtype, found, recorded, spec.rate, spec.delay)
            )
    return out


def _timing_text(t: Timing, gap: Gap | None, start: int | None) -> str:
    """Observed rate and delay, and the longest gap (from the recording's `start`), as
    `info --timing` prints them beside the count."""
    rate = (
        f"  rate {t.rate_median:.4g} Hz (p5 {t.rate_p5:.4g})"
        if t.rate_median is not None and t.rate_p5 is not None
        else "  rate ?"
    )
    delay = (
        f", delay {t.delay_median:.4g} s (p95 {t.delay_p95:.4g})"
        if t.delay_median is not None and t.delay_p95 is not None
        else ""
    )
    longest = (
        f", longest gap {seconds_text(gap.length)} s at {seconds_text(gap.start - (start or 0))} s"
        if gap is not None
        else ""
    )
    return rate + delay + longest


def _declared(binds: Sequence[Binding]) -> dict[str, str]:
    """Per recording topic, the quality the spec topics it binds declare, in SSL_T's words."""
    out: dict[str, list[str]] = {}
    for b in binds:
        said = ", ".join(f"{name} {value}" for name, value in format_quality(b))
        if b.bound is not None and said:
            out.setdefault(b.bound, []).append(f"{said} ({stream_name(b.platform, b.topic)})")
    return {topic: "; declared " + "; ".join(said) for topic, said in out.items()}


def render(infos: Sequence[RecordingInfo], binds: Sequence[Binding] | None) -> str:
    lines = []
    declared = _declared(binds or ())
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
        for t in info.topics:
            lines.append(
                f"  {t.name:<{width}}  {t.msgtype}  {t.count if t.count is not None else '?'}"
                + (
                    _timing_text(t.timing, t.gap, info.start) + declared.get(t.name, "")
                    if t.timing
                    else ""
                )
            )
            across = max((len(f.path) for f in t.fields), default=0)
            lines += [f"      {f.path:<{across}}  {f.ros_type}" for f in t.fields]
        lines += [f"  damaged: {d}" for d in info.damage]
    for b in binds or ():
        where = f"{stream_name(b.platform, b.topic)} ({b.msgtype})"
        if b.bound is None:
            lines.append(f"{where}: in no recording")
        elif b.recorded_type is not None and not message_type_fits(b.recorded_type, b.msgtype):
            lines.append(f"{where}: {b.bound} carries {b.recorded_type}, not {b.msgtype}")
        else:
            lines.append(f"{where} ← {b.bound}")
    return "\n".join(lines)
