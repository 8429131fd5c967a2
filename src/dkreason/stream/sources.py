"""Where messages come from: ROS recordings, JSON lines, or a live push.

Every source yields `(topic, available_ns, valid_ns, message)` in recording order.  The valid
time is the message's `header.stamp` when it has one, else the record time; the available time
is the record time.  Times are integer nanoseconds.
"""

from __future__ import annotations

import json
import queue
from collections.abc import Iterator, Sequence
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Any, Protocol

from ..errors import DkError, ParseError, Span
from . import fields

Message = tuple[str, int, int, Any]
NS = 10**9


def to_ns(seconds: Any, what: str = "time") -> int:
    """Exact seconds (JSON decimals, ints, Fractions) → integer nanoseconds."""
    try:
        value = Fraction(seconds) if not isinstance(seconds, float) else Fraction(repr(seconds))
    except (TypeError, ValueError):
        raise DkError(f"{what} must be a number, not {seconds!r}") from None
    ns = value * NS
    if ns.denominator != 1:
        raise DkError(f"{what} {seconds} is finer than a nanosecond")
    return int(ns)


class Source(Protocol):
    name: str
    dicts: bool  # messages are dicts (JSON) rather than objects (ROS)

    def types(self) -> dict[str, str]:
        """Topic → message type, as far as known before reading."""
        ...

    def check_field(self, topic: str, field: str) -> str | None:
        """Why `field` is missing from `topic`'s messages (None: present or not knowable)."""
        ...

    def messages(self, topics: set[str]) -> Iterator[Message]: ...

    def count(self, topics: set[str] | None) -> int | None:
        """Messages on `topics` (None: all), when the source knows."""
        ...


class RosbagSource:
    """ROS 1 `.bag`, ROS 2 bag folders (sqlite3 or MCAP) and bare `.mcap`/`.db3` files.

    Message definitions come from the recording; `msg_files` (`pkg/msg/Name.msg`) supply
    custom types for recordings that carry none."""

    dicts = False

    def __init__(self, path: Path, msg_files: Sequence[Path] = ()) -> None:
        self.name = str(path)
        self.path = path
        if not path.exists():
            raise DkError(f"{path}: no such recording")
        from rosbags.highlevel import AnyReader

        default = _typestore(msg_files, ros1=path.suffix == ".bag") if msg_files else None
        try:
            self.reader = AnyReader([path], default_typestore=default)
            self.reader.open()
        except Exception as exc:  # rosbags raises several kinds for unreadable files
            raise DkError(f"{path}: not a readable ROS recording ({_why(exc)})") from None

    def types(self) -> dict[str, str]:
        return {c.topic: c.msgtype for c in self.reader.connections}

    def check_field(self, topic: str, field: str) -> str | None:
        msgtype = self.types().get(topic)
        if msgtype is None:
            return None
        return fields.check(self.reader.typestore.fielddefs, msgtype, field)

    def count(self, topics: set[str] | None) -> int | None:
        return sum(c.msgcount for c in self.reader.connections
                   if topics is None or c.topic in topics)

    def messages(self, topics: set[str]) -> Iterator[Message]:
        connections = [c for c in self.reader.connections if c.topic in topics]
        if not connections:
            return
        deserialize = self.reader.deserialize
        try:
            for connection, t_ns, raw in self.reader.messages(connections=connections):
                msg = deserialize(raw, connection.msgtype)
                header = getattr(msg, "header", None)
                stamp = getattr(header, "stamp", None)
                valid = stamp.sec * NS + stamp.nanosec if stamp is not None else t_ns
                yield connection.topic, t_ns, valid, msg
        except Exception as exc:  # a damaged file can fail anywhere in rosbags
            raise DkError(f"{self.name}: damaged recording ({_why(exc)})") from None

    def close(self) -> None:
        self.reader.close()


def _typestore(msg_files: Sequence[Path], ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    for path in msg_files:
        if path.suffix != ".msg" or path.parent.name != "msg":
            raise DkError(f"{path}: expected a message definition pkg/msg/Name.msg")
        name = f"{path.parent.parent.name}/msg/{path.stem}"
        try:
            types.update(get_types_from_msg(path.read_text(encoding="utf-8"), name))
        except Exception as exc:
            raise DkError(f"{path}: not a message definition ({_why(exc)})") from None
    store.register(types)
    return store


def _why(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:200]


class JsonlSource:
    """JSON lines `{"topic": "topic3", "time": 12.0, "msg": {"id": 1, "spd": 61.5}}`, with an
    optional `"available"` time (seconds); a `"header": {"stamp": …}` sets the valid time."""

    dicts = True

    def __init__(self, path: Path) -> None:
        self.name, self.path = str(path), path
        if not path.is_file():
            raise DkError(f"{path}: no such file")

    def types(self) -> dict[str, str]:
        return {}

    def check_field(self, topic: str, field: str) -> str | None:
        return None  # JSON carries no definitions: a missing field is found at its message

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def messages(self, topics: set[str]) -> Iterator[Message]:
        with self.path.open(encoding="utf-8") as handle:
            for n, line in enumerate(handle, 1):
                if not line.strip():
                    continue
                try:
                    row = json.loads(line, parse_float=Decimal)
                    topic, msg = row["topic"], row["msg"]
                    valid = to_ns(row["time"])
                    available = to_ns(row.get("available", row["time"]), "available time")
                except (json.JSONDecodeError, KeyError, TypeError, DkError) as exc:
                    what = exc.msg if isinstance(exc, json.JSONDecodeError) else \
                        f"missing {exc}" if isinstance(exc, KeyError) else str(exc)
                    raise ParseError(f"not a message line ({what})", Span(self.name, n)) \
                        from None
                if topic in topics:
                    yield topic, available, valid, _floats(msg)


def _floats(value: Any) -> Any:
    if isinstance(value, Decimal):
        return float(value)
    if isinstance(value, dict):
        return {k: _floats(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_floats(v) for v in value]
    return value


class PushSource:
    """Samples pushed from any live source (a ROS callback, a socket reader, a test)."""

    dicts = True
    name = "<push>"
    _END = object()

    def __init__(self) -> None:
        self._queue: queue.Queue[Any] = queue.Queue()

    def push(self, topic: str, time: Any, msg: Any, available: Any = None) -> None:
        valid = to_ns(time)
        self._queue.put((topic, valid if available is None else to_ns(available), valid, msg))

    def close(self) -> None:
        self._queue.put(self._END)

    def types(self) -> dict[str, str]:
        return {}

    def check_field(self, topic: str, field: str) -> str | None:
        return None

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def messages(self, topics: set[str]) -> Iterator[Message]:
        while (item := self._queue.get()) is not self._END:
            if item[0] in topics:
                yield item


class McapStreamSource:
    """An MCAP file whose index is damaged (a recording cut off mid-write): read it record by
    record, so every message before the damage is used, then say where it broke."""

    dicts = False

    def __init__(self, path: Path, msg_files: Sequence[Path] = ()) -> None:
        self.name, self.path = str(path), path
        self.note = f"{path}: index damaged or missing, reading the recording sequentially"
        self.store = _typestore(msg_files, ros1=False)
        self.channels: dict[int, tuple[str, str]] = {}  # id → topic, msgtype
        self._scan_types()

    def _records(self) -> Iterator[Any]:
        from mcap.stream_reader import StreamReader

        with self.path.open("rb") as handle:
            yield from StreamReader(handle).records

    def _learn(self, record: Any, schemas: dict[int, str]) -> None:
        from mcap.records import Channel, Schema
        from rosbags.typesys import get_types_from_msg

        if isinstance(record, Schema) and record.encoding == "ros2msg":
            schemas[record.id] = record.name
            try:
                self.store.register(get_types_from_msg(record.data.decode(), record.name))
            except Exception as exc:
                raise DkError(f"{self.name}: message definition {record.name} unreadable "
                              f"({_why(exc)})") from None
        elif isinstance(record, Channel) and record.schema_id in schemas:
            self.channels[record.id] = (record.topic, schemas[record.schema_id])

    def _scan_types(self) -> None:
        from mcap.records import Message

        schemas: dict[int, str] = {}
        try:
            for record in self._records():
                if isinstance(record, Message) and self.channels:
                    break
                self._learn(record, schemas)
        except Exception as exc:
            if not self.channels:
                raise DkError(f"{self.name}: not a readable ROS recording ({_why(exc)})") \
                    from None

    def types(self) -> dict[str, str]:
        return dict(self.channels.values())

    def check_field(self, topic: str, field: str) -> str | None:
        msgtype = self.types().get(topic)
        return None if msgtype is None else fields.check(self.store.fielddefs, msgtype, field)

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def messages(self, topics: set[str]) -> Iterator[Message]:
        from mcap.records import Message as McapMessage

        schemas: dict[int, str] = {}
        n = 0
        try:
            for record in self._records():
                if not isinstance(record, McapMessage):
                    self._learn(record, schemas)
                    continue
                topic, msgtype = self.channels.get(record.channel_id, ("", ""))
                if topic not in topics:
                    continue
                msg = self.store.deserialize_cdr(record.data, msgtype)
                header = getattr(msg, "header", None)
                stamp = getattr(header, "stamp", None)
                valid = stamp.sec * NS + stamp.nanosec if stamp is not None else record.log_time
                n += 1
                yield topic, record.log_time, valid, msg
        except Exception as exc:
            why = "the file ends in the middle of a record" if type(exc).__name__ == \
                "EndOfFile" else _why(exc)
            raise DkError(f"{self.name}: damaged recording after {n} messages ({why})") \
                from None


def open_source(path: Path, msg_files: Sequence[Path] = ()) -> Source:
    if path.suffix == ".jsonl" or path.suffix == ".json":
        return JsonlSource(path)
    try:
        return RosbagSource(path, msg_files)
    except DkError:
        mcap = path if path.suffix == ".mcap" else next(iter(sorted(path.glob("*.mcap"))), None) \
            if path.is_dir() else None
        if mcap is None:
            raise
        return McapStreamSource(mcap, msg_files)
