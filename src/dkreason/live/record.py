"""Record a run: the relevant topics' messages, byte for byte, and what the monitor said.

One MCAP file (ROS 2 profile) that Foxglove opens and `dkreason monitor --source` replays:
each topic a `cdr` channel with its `ros2msg` schema, the payload kept byte for byte (a ROS 1
bag's converted to CDR: rosbags reads no ROS 1 encoding in MCAP); the verdicts, violations
and federation changes twice: on `/dkreason/log` as `foxglove.Log` (what Foxglove's Log
panel reads, eventlog.py) and on the structured JSON channel `/dkreason/events`.

Live (`--ros2`), a message's log time is the time the monitor took as its valid time when
the message has no header stamp (so a replay reads the same times) and its arrival
otherwise, its publish time the publisher's source time when the attachment gave one.
Offline (`RecordedRun`), both are its record time, and `--clips` cuts one small file per
violation from a margin before its witness window to a margin after it.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Iterable, Iterator, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

from ..errors import DkError
from ..eventlog import INFO, LOG_SCHEMA, LOG_TOPIC, EventLog, log, ns
from ..monitor import Event, Monitor, MonitorRun, Watcher
from ..progress import Verdict
from ..stream.binding import Recordings
from ..stream.sources import Raw
from ..stream.units import NS

EVENTS = "/dkreason/events"
EVENT_SCHEMA = {
    "title": "dkreason event",
    "description": "A verdict, a stream constraint violation or a federation change",
    "type": "object",
    "properties": {
        "formula": {"type": "string"},
        "verdict": {"type": ["boolean", "null"]},
        "violation": {"type": "string"},
        "event": {"type": "string"},
        "time": {"type": ["number", "null"]},
        "feature": {"type": "string"},
        "topic": {"type": "string"},
        "detail": {"type": "string"},
    },
}


class RecordError(DkError):
    """The record file cannot be written (a full disk): the run stops, what is written kept."""


class Recorder:
    def __init__(
        self, path: Path, store: Any = None, option: str = "--record", *, force: bool = False
    ) -> None:
        """`store`: the rosbags typestore live messages' definitions come from.  An existing
        file is refused (a run recorded before is not lost to a typo) unless `force`."""
        from mcap.writer import Writer

        if not path.parent.is_dir():
            raise DkError(f"{option} {path}: no such directory {path.parent}")
        try:  # "x": created here, or refused if it exists, in one step (no race to lose)
            self.file = path.open("wb" if force else "xb")
        except FileExistsError:
            raise DkError(
                f"{option} {path}: the file exists (give --force to overwrite it)"
            ) from None
        except OSError as exc:
            raise DkError(f"{option} {path}: {exc.strerror}") from None
        self.path, self.store, self.option = path, store, option
        self.closed = False
        self.writer = Writer(self.file)
        self.writer.start(profile="ros2", library="dkreason")
        self.channels: dict[str, int] = {}
        self.sequence = 0
        self.said = EventLog()
        self.events = self._json(EVENTS, "dkreason/Event", EVENT_SCHEMA)
        self.log = self._json(LOG_TOPIC, "foxglove.Log", LOG_SCHEMA)

    def _json(self, topic: str, name: str, schema: dict[str, Any]) -> int:
        data = json.dumps(schema).encode()
        return self.writer.register_channel(
            topic, "json", self.writer.register_schema(name=name, encoding="jsonschema", data=data)
        )

    def message(
        self, topic: str, msgtype: str, log_time: int, publish_time: int, payload: bytes
    ) -> None:
        """A live message (CDR), its definition from the typestore."""
        channel = self.channels.get(topic)
        if channel is None:
            text, _ = self.store.generate_msgdef(msgtype, ros_version=2)
            channel = self._channel(topic, msgtype, text)
        self._add(channel, log_time, publish_time, payload)

    def raw(self, message: Raw) -> None:
        """A recorded message (CDR)."""
        channel = self.channels.get(message.topic)
        if channel is None:
            channel = self._channel(message.topic, message.msgtype, message.definition)
        self._add(channel, message.time, message.time, message.data)

    def _channel(self, topic: str, msgtype: str, definition: str) -> int:
        schema = self.writer.register_schema(
            name=msgtype, encoding="ros2msg", data=definition.encode()
        )
        self.channels[topic] = self.writer.register_channel(topic, "cdr", schema)
        return self.channels[topic]

    def event(self, time: int, event: Any) -> None:
        """A verdict, violation or change, at its own time or `time` (ns) when it has none:
        its JSON on the events channel, its log lines on the log channel."""
        data = json.dumps(event.to_json(), ensure_ascii=False, default=str).encode()
        self._add(self.events, ns(event.time, time), ns(event.time, time), data)
        for at, line in self.said.lines(event, time):
            self._add(self.log, at, at, json.dumps(line, ensure_ascii=False).encode())

    def note(self, at: int, text: str) -> None:
        """A log line of dkreason's own at `at` (ns)."""
        data = json.dumps(log(at, INFO, "dkreason", text), ensure_ascii=False).encode()
        self._add(self.log, at, at, data)

    def _add(self, channel: int, log_time: int, publish_time: int, data: bytes) -> None:
        self.sequence += 1
        try:
            self.writer.add_message(
                channel_id=channel,
                log_time=max(log_time, 0),
                publish_time=max(publish_time, 0),
                data=data,
                sequence=self.sequence & 0xFFFFFFFF,
            )
        except OSError as exc:
            self.closed = True  # nothing more goes in; closing is quiet
            with contextlib.suppress(OSError):
                self.file.close()
            raise RecordError(
                f"{self.option} {self.path}: {exc.strerror or exc}; the messages "
                f"before it are in the file"
            ) from None

    def close(self) -> None:
        """The file's index and summary written (a file cut short still reads, up to the
        cut, as a damaged recording)."""
        if self.closed:
            return
        self.closed = True
        try:
            self.writer.finish()  # type: ignore[no-untyped-call]
            self.file.close()
        except OSError as exc:
            with contextlib.suppress(OSError):
                self.file.close()
            raise RecordError(
                f"{self.option} {self.path}: {exc.strerror or exc}; the file is cut "
                f"short (it reads as a damaged recording)"
            ) from None


class RecordedRun(MonitorRun):
    """A run over recordings that, once its events have been read, writes the relevant
    topics and what was said to `record`, and one clip per violation (a violated verdict)
    to the folder `clips`: the topics' messages recorded from `margin` s before its witness
    window to `margin` s after it, and the verdict.  On an error in the data: what came
    before it."""

    def __init__(
        self,
        monitor: Monitor,
        source: Recordings,
        record: Path | None = None,
        clips: Path | None = None,
        margin: Fraction = Fraction(2),
        *,
        speed: float = 0,
        watcher: Watcher | None = None,
        force: bool = False,
    ) -> None:
        """`force`: existing files are overwritten (else refused: `record` before the run)."""
        problem = None
        if record is not None and not record.parent.is_dir():
            problem = f"--record {record}: no such directory {record.parent}"
        elif record is not None and record.exists() and not force:
            problem = f"--record {record}: the file exists (give --force to overwrite it)"
        elif clips is not None and not clips.is_dir():
            problem = f"--clips {clips}: no such directory"
        if problem is not None:
            source.close()
            if watcher is not None:
                watcher.close()
            raise DkError(problem)
        super().__init__(monitor, source, speed=speed, watcher=watcher)
        self.recordings, self.record, self.clips, self.margin = source, record, clips, margin
        self.force = force
        self.written: list[tuple[Path, Verdict]] = []
        """The clips written, each with the verdict it shows."""

    def events(self, progress: Callable[[int], None] | None = None) -> Iterator[Event]:
        said: list[Event] = []
        try:
            for event in super().events(progress):
                said.append(event)
                yield event
        except DkError:
            self._write(said)
            raise
        self._write(said)

    def _write(self, events: Sequence[Event]) -> None:
        raw = self.recordings.raw(list(self.processor.wanted))
        end = self.processor.horizon() or 0  # for an event without a time
        cut = round(self.margin * NS)
        outs: list[_Out] = []
        try:
            if self.record is not None:
                outs.append(_Out(Recorder(self.record, force=self.force), None, events, end))
                start = self.source.first_record()
                if start is not None:  # the copy's time axis starts where the original's did
                    outs[0].recorder.note(start, f"monitoring {self.source.name}")
            violated = [
                e
                for e in events
                if isinstance(e, Verdict) and e.verdict is False and e.window and not e.update
            ]
            for n, v in enumerate(violated if self.clips is not None else (), 1):
                assert self.clips is not None and v.window is not None
                path = self.clips / f"violation-{n}.mcap"
                span = (ns(v.window[0], end) - cut, ns(v.window[1], end) + cut)
                clip = Recorder(path, option="--clips", force=self.force)
                outs.append(_Out(clip, span, [v], end))
                self.written.append((path, v))
            for message in raw:
                for out in outs:
                    out.message(message)
            for out in outs:
                out.flush(None)
        finally:
            raw.close()
            for out in outs:
                out.recorder.close()


class _Out:
    """One file being written: the messages within its span (None: all), and its events in
    time order among them."""

    def __init__(
        self, recorder: Recorder, span: tuple[int, int] | None, events: Iterable[Event], end: int
    ) -> None:
        self.recorder, self.span, self.end = recorder, span, end
        self.events = sorted(events, key=lambda e: ns(e.time, end), reverse=True)

    def message(self, message: Raw) -> None:
        if self.span is None or self.span[0] <= message.time <= self.span[1]:
            self.flush(message.time)
            self.recorder.raw(message)

    def flush(self, until: int | None) -> None:
        """The events up to `until` (ns; None: all) written."""
        while self.events and (until is None or ns(self.events[-1].time, self.end) <= until):
            self.recorder.event(self.end, self.events.pop())
