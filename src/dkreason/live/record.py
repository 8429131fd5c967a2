"""Record a live run: the relevant topics' messages as received, and what the monitor said.

One MCAP file (ROS 2 profile) that Foxglove opens and `dkreason monitor --source` replays:
each topic a `cdr` channel with its `ros2msg` schema, the payload kept byte for byte; the
verdicts, violations and federation changes a `json` channel `/dkreason/events` with a JSON
schema.  A message's log time is the time the monitor took as its valid time when the message
has no header stamp (so a replay reads the same times) and its arrival otherwise; its publish
time is the publisher's source time when the attachment gave one.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

from ..errors import DkError

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
    def __init__(self, path: Path, store: Any) -> None:
        """`store`: the rosbags typestore the messages' definitions come from."""
        from mcap.writer import Writer

        if not path.parent.is_dir():
            raise DkError(f"--record {path}: no such directory {path.parent}")
        try:
            self.file = path.open("wb")
        except OSError as exc:
            raise DkError(f"--record {path}: {exc.strerror}") from None
        self.path, self.store = path, store
        self.closed = False
        self.writer = Writer(self.file)
        self.writer.start(profile="ros2", library="dkreason")
        self.channels: dict[str, int] = {}
        self.sequence = 0
        schema = self.writer.register_schema(
            name="dkreason/Event", encoding="jsonschema", data=json.dumps(EVENT_SCHEMA).encode()
        )
        self.events = self.writer.register_channel(EVENTS, "json", schema)

    def message(
        self, topic: str, msgtype: str, log_time: int, publish_time: int, payload: bytes
    ) -> None:
        channel = self.channels.get(topic)
        if channel is None:
            text, _ = self.store.generate_msgdef(msgtype, ros_version=2)
            schema = self.writer.register_schema(
                name=msgtype, encoding="ros2msg", data=text.encode()
            )
            channel = self.channels[topic] = self.writer.register_channel(topic, "cdr", schema)
        self._add(channel, log_time, publish_time, payload)

    def event(self, time: int, event: dict[str, Any]) -> None:
        """A verdict, violation or change (`to_json()`), logged at `time` (ns)."""
        self._add(
            self.events, time, time, json.dumps(event, ensure_ascii=False, default=str).encode()
        )

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
                f"--record {self.path}: {exc.strerror or exc}; the messages "
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
                f"--record {self.path}: {exc.strerror or exc}; the file is cut "
                f"short (it reads as a damaged recording)"
            ) from None
