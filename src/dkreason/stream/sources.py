"""Where messages come from: ROS recordings, JSON lines, or a live push.

A source is asked for the fields each topic's messages must give (`wanted`) and yields
`(topic, available_ns, valid_ns, values)` in recording order, `values` in the order asked.
The valid time is the message's `header.stamp` when it has one, else the record time; the
available time is the record time.  Times are integer nanoseconds.  ROS messages are read
field by field where their layout allows (fastread.py) and deserialised in full otherwise.
"""

from __future__ import annotations

import queue
from collections.abc import Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import Any, Protocol

from ..errors import DkError, ParseError, Span
from ..inputs import files
from . import fields
from .chunks import bound_rosbags
from .damaged import DamagedRecording, SequentialSource, check_magic, declared_size, kind_of
from .mcapread import IndexedMcap, Survey, open_indexed
from .typestore import (
    load_typestore,
    msg_types,
    plain,
    ros_reader,
    store_name,
    why,
    with_definitions,
)
from .units import NS, to_ns

Message = tuple[str, int, int, tuple[Any, ...]]
Record = tuple[str, int, int, Any]  # a whole message: topic, available, valid, plain data
Wanted = dict[str, list[str]]  # topic → fields, in the order the values are yielded


@dataclass(frozen=True, slots=True)
class Raw:
    """A message as recorded, to be copied (`--record`, `--clips`): its topic, record time
    (ns) and CDR bytes, and what its channel needs: the message type and its definition's
    text (ros2msg)."""

    topic: str
    time: int
    data: bytes
    msgtype: str
    definition: str


class Source(Protocol):
    name: str

    def types(self) -> dict[str, str]:
        """Topic → message type, as far as known before reading."""
        ...

    def check_field(self, topic: str, field: str) -> str | None:
        """Why `field` is missing from `topic`'s messages (None: present or not knowable)."""
        ...

    def messages(self, wanted: Wanted) -> Iterator[Message]: ...

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        """(number, bool, string, message or array; the ROS type) of a field, when known."""
        ...

    def count(self, topics: set[str] | None) -> int | None:
        """Messages on `topics` (None: all), when the source knows."""
        ...

    def first_record(self) -> int | None:
        """The record time (ns) of the recording's first message, of any topic, as `dkreason
        info` shows it, once known (None: not yet, or never): the start of the time axis,
        whatever was asked of the recording."""
        ...

    def last_record(self) -> int | None:
        """The record time (ns) of the recording's last message, of any topic, once it has
        been read (None: not known): where the stream ends, whatever was asked of it."""
        ...

    def close(self) -> None:
        """Release the file (the monitor calls it however the replay ends)."""
        ...


class RosbagSource:
    """ROS 1 `.bag`, ROS 2 bag folders (sqlite3 or MCAP) and bare `.mcap`/`.db3` files.

    Message definitions come from the recording; one that stores none (a Humble-era `.db3`)
    is read with rosbags' standard definitions of `typestore` (default: ros1_noetic for a
    `.bag`, else ros2_humble).  `msg_files` (`pkg/msg/Name.msg`) add to those and replace a
    recording's own definition of the same type (a bag recorded with a wrong one)."""

    def __init__(
        self, path: Path, msg_files: Sequence[Path] = (), typestore: str | None = None
    ) -> None:
        self.name = str(path)
        self.path = path
        self._indexed: IndexedMcap | None = None
        if not path.exists():
            raise DkError(f"{path}: no such recording")
        from rosbags.highlevel import AnyReader

        ros1 = path.suffix == ".bag"
        given = msg_types(msg_files)
        default = load_typestore(given, ros1, typestore)
        _foreign_channels_allowed()
        bound_rosbags()
        try:
            self.reader = AnyReader([path], default_typestore=default)
            self.reader.open()
        except Exception as exc:  # rosbags raises several kinds for unreadable files
            raise DkError(f"{path}: not a readable ROS recording ({why(exc)})") from None
        self.connections = [c for c in self.reader.connections if _ros(c)]
        self.first = int(self.reader.start_time) if self.connections else None
        foreign = sorted(
            {
                f"{c.topic} ({getattr(c.ext, 'serialization_format', '?')})"
                for c in self.reader.connections
                if not _ros(c)
            }
        )
        notes = (
            [f"{path}: channels not in a ROS encoding skipped: {', '.join(foreign)}"]
            if foreign
            else []
        )
        if not msg_files and typestore is None and any(not c.msgdef.data for c in self.connections):
            notes.append(
                f"{path} stores no message definitions: using rosbags' "
                f"{store_name(ros1, None)} ones (--typestore, --msg)"
            )
        replaced = sorted(
            name
            for name, definition in given.items()
            if self.reader.typestore.fielddefs.get(name, definition) != definition
        )
        if replaced:
            self.reader.typestore = with_definitions(self.reader.typestore, given)
            notes = [
                f"{name}: the definition of --msg replaces the one {path} stores"
                for name in replaced
            ]
        self.note = "; ".join(notes)
        self.store = self.reader.typestore  # closing the reader empties its own

    def types(self) -> dict[str, str]:
        return {c.topic: c.msgtype for c in self.connections}

    def check_field(self, topic: str, field: str) -> str | None:
        msgtype = self.types().get(topic)
        if msgtype is None:
            return None
        return fields.check(self.reader.typestore.fielddefs, msgtype, field)

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        msgtype = self.types().get(topic)
        return (
            None
            if msgtype is None
            else fields.kind(self.reader.typestore.fielddefs, msgtype, field)
        )

    def first_record(self) -> int | None:
        return self.first

    def last_record(self) -> int | None:
        return int(self.reader.end_time) - 1 if self.connections else None

    def count(self, topics: set[str] | None) -> int | None:
        return sum(c.msgcount for c in self.connections if topics is None or c.topic in topics)

    def messages(self, wanted: Wanted) -> Iterator[Message]:
        connections = [c for c in self.connections if c.topic in wanted]
        if not connections:
            return
        fielddefs = self.reader.typestore.fielddefs
        readers = {
            id(c): (
                c,
                c.topic,
                *ros_reader(
                    fielddefs,
                    c.msgtype,
                    wanted[c.topic],
                    not self.reader.is2,
                    self.reader.deserialize,
                ),
            )
            for c in connections
        }
        n = 0
        unchecked = set(readers)
        keyed: dict[Any, Any] = {}
        last: dict[Any, int] | None = None
        try:
            for batch, by in self._batches(connections):
                if by is not last:  # the batches' keys, straight to their readers
                    keyed, last = {key: readers[c] for key, c in by.items()}, by
                for key, t_ns, raw in batch:
                    connection, topic, read, stamped = keyed[key]
                    if unchecked and id(connection) in unchecked:  # once a topic: the reference
                        unchecked.discard(id(connection))
                        _decodes(self.reader.deserialize, raw, connection)
                    values = read(raw)
                    n += 1
                    yield topic, t_ns, values[-2] * NS + values[-1] if stamped else t_ns, values
        except DkError:
            raise
        except Exception as exc:  # a damaged file can fail anywhere in rosbags
            raise DamagedRecording(
                f"{self.name}: damaged recording ({why(exc)}); {n} "
                f"messages before it were monitored, the rest is lost"
            ) from None
        lost = None if self._indexed is None else self._indexed.damage()
        if lost is not None:  # read around: the chunks before and after the damage
            raise DamagedRecording(
                f"{self.name}: damaged recording: {lost}; the {n} messages read were monitored"
            )

    def _batches(
        self, connections: list[Any]
    ) -> Iterator[tuple[Iterable[tuple[Any, int, bytes]], dict[Any, int]]]:
        """Messages in recording order, in batches: (key, record time, serialised message),
        and what each key is (the id of its connection).  An indexed MCAP file is read through
        mcapread, a chunk a batch (~5× rosbags' rate); anything else through rosbags."""
        if self._indexed is not None:  # asked again: the file is read again from the start
            self._indexed.close()
            self._indexed = None
        by_topic = {c.topic: c for c in connections}
        found = kind_of(self.path)  # a bare file, or a bag folder's only storage file
        indexed = (
            open_indexed(found[1])
            if self.reader.is2
            and found is not None
            and found[0] == "mcap"
            and len(by_topic) == len(connections)
            else None
        )
        channels = (
            {}
            if indexed is None
            else {
                ch: id(by_topic[topic])
                for ch, (topic, encoding) in indexed.channels.items()
                if topic in by_topic and encoding == "cdr"
            }
        )
        if indexed is None or len(set(channels.values())) != len(connections):
            if indexed is not None:  # a topic in another encoding (ros1 in MCAP): rosbags'
                indexed.close()
            same = {id(c): id(c) for c in connections}
            for connection, t_ns, raw in self.reader.messages(connections=connections):
                yield ((id(connection), t_ns, raw),), same
            return
        self._indexed = indexed
        for batch in indexed.batches(channels):
            yield batch, channels

    def survey(self) -> Survey | None:
        """What an indexed MCAP file's chunks hold, read from them (counts, span, damage);
        None for any other file, whose index is taken at its word."""
        found = kind_of(self.path)
        indexed = (
            open_indexed(found[1])
            if self.reader.is2 and found is not None and found[0] == "mcap"
            else None
        )
        if indexed is None:
            return None
        try:
            return indexed.survey(
                ch for ch, (_, encoding) in indexed.channels.items() if encoding in ENCODINGS
            )
        finally:
            indexed.close()

    def raw(self, topics: Collection[str]) -> Iterator[Raw]:
        """The messages on `topics` as recorded, read afresh (after a run, the file closed):
        CDR byte for byte; a ROS 1 message converted to CDR (rosbags reads no ROS 1 encoding
        in an MCAP file).  Definitions from this source's types (`--msg` ones included)."""
        from rosbags.highlevel import AnyReader

        store = self.store
        definitions: dict[str, str] = {}
        try:
            with AnyReader([self.path], default_typestore=store) as reader:
                wanted = [c for c in reader.connections if c.topic in topics and _ros(c)]
                for c, t_ns, data in reader.messages(connections=wanted):
                    cdr = (
                        bytes(store.ros1_to_cdr(data, c.msgtype))
                        if not reader.is2 or _encoding(c) == "ros1"
                        else data
                    )
                    if c.msgtype not in definitions:
                        definitions[c.msgtype] = store.generate_msgdef(c.msgtype, ros_version=2)[0]
                    yield Raw(c.topic, t_ns, cdr, c.msgtype, definitions[c.msgtype])
        except DkError:
            raise
        except Exception as exc:  # a damaged file can fail anywhere in rosbags
            raise DamagedRecording(f"{self.name}: damaged recording ({why(exc)})") from None

    def records(self) -> Iterator[Record]:
        """Every message in full, as plain data (what a live platform node publishes)."""
        try:
            for connection, t_ns, raw in self.reader.messages(connections=self.connections):
                msg = plain(self.reader.deserialize(raw, connection.msgtype))
                stamp = msg.get("header", {}).get("stamp") if isinstance(msg, dict) else None
                valid = (
                    stamp["sec"] * NS + stamp.get("nanosec", stamp.get("nsec", 0))
                    if isinstance(stamp, dict) and "sec" in stamp
                    else t_ns
                )
                yield connection.topic, t_ns, valid, msg
        except Exception as exc:
            raise DkError(f"{self.name}: damaged recording ({why(exc)})") from None

    def close(self) -> None:
        if self._indexed is not None:
            self._indexed.close()
        if self.reader.stack is not None:
            self.reader.close()


ENCODINGS = ("cdr", "ros1")  # a channel's, when it is ROS (an MCAP may hold JSON, protobuf)


def _encoding(connection: Any) -> str:
    """A ROS 2 recording's channel's encoding (an MCAP file's may be ros1, json, …)."""
    return str(getattr(connection.ext, "serialization_format", "cdr"))


def _ros(connection: Any) -> bool:
    """A channel in a ROS encoding."""
    return _encoding(connection) in ENCODINGS


def _foreign_channels_allowed() -> None:
    """rosbags refuses an MCAP file at the first schema not in a ROS encoding (a JSON channel
    that Foxglove or `--record` wrote beside the ROS ones); read such a schema as carrying no
    ROS definition instead, so its channel can be skipped (`_ros`)."""
    from rosbags.interfaces import MessageDefinition, MessageDefinitionFormat
    from rosbags.rosbag2 import storage_mcap

    strict = storage_mcap.get_msgdef
    if getattr(strict, "lenient", False):
        return

    def lenient(schema: Any) -> Any:
        if schema is not None and schema.encoding not in ("ros2msg", "ros2idl", "omgidl", ""):
            return MessageDefinition(MessageDefinitionFormat.NONE, "")
        return strict(schema)

    lenient.lenient = True  # type: ignore[attr-defined]
    storage_mcap.get_msgdef = lenient


def _decodes(deserialize: Any, raw: Any, connection: Any) -> None:
    """A topic's first message must decode to its definition exactly (rosbags checks the
    size): a wrong definition would otherwise read garbage at the offsets it implies."""
    try:
        deserialize(raw, connection.msgtype)
    except Exception as exc:
        raise DkError(
            f"{connection.topic}: its messages do not match the definition of "
            f"{connection.msgtype} ({why(exc)}); give the right one with --msg"
        ) from None


def dict_reader(name: str, wanted: Wanted) -> Any:
    """(topic, time, message dict) → values of the fields wanted on that topic."""
    getters = {
        topic: [(f, fields.accessor(f, dicts=True)) for f in fs] for topic, fs in wanted.items()
    }

    def read(topic: str, t_ns: int, msg: Any) -> tuple[Any, ...]:
        out = []
        for field, get in getters[topic]:
            try:
                out.append(get(msg))
            except (KeyError, IndexError, TypeError):
                raise DkError(
                    f"{name}: the message on {topic} at {t_ns / NS:g} s has no field {field}"
                ) from None
        return tuple(out)

    return read


class JsonlSource:
    """JSON lines `{"topic": "topic3", "time": 12.0, "msg": {"id": 1, "spd": 61.5}}`, with an
    optional `"available"` time (seconds); a `"header": {"stamp": …}` sets the valid time."""

    def __init__(self, path: Path) -> None:
        """`-` reads standard input (a live feed)."""
        self.name, self.path = ("<stdin>" if str(path) == "-" else str(path)), path
        self.first: int | None = None  # the first record time read, of any topic
        self.last: int | None = None  # the latest record time read, of any topic
        if str(path) != "-":
            files.regular(path)

    def types(self) -> dict[str, str]:
        return {}

    def check_field(self, topic: str, field: str) -> str | None:
        return None  # JSON carries no definitions: a missing field is found at its message

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        return None  # nor types: a value of the wrong kind is found at its message

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def messages(self, wanted: Wanted) -> Iterator[Message]:
        read = dict_reader(self.name, wanted)
        for topic, available, valid, msg in self.records():
            if self.first is None:
                self.first = available
            self.last = available if self.last is None else max(self.last, available)
            if topic in wanted:
                yield topic, available, valid, read(topic, valid, msg)

    def first_record(self) -> int | None:
        return self.first

    def last_record(self) -> int | None:
        return self.last

    def records(self) -> Iterator[Record]:
        for n, line in files.lines(self.path, self.name):
            if not line.strip():
                continue
            where = Span(self.name, n)
            row = files.json_value(line, where)
            if (
                not isinstance(row, dict)
                or not isinstance(row.get("topic"), str)
                or not isinstance(row.get("msg"), dict)
                or "time" not in row
            ):
                raise ParseError(
                    'not a message line (expected {"topic": "…", "time": seconds, "msg": {…}})',
                    where,
                )
            try:
                valid = to_ns(row["time"])
                available = to_ns(row.get("available", row["time"]), "available time")
                msg = _floats(row["msg"])
            except DkError as exc:
                raise ParseError(f"not a message line ({exc})", where) from None
            except RecursionError:
                raise ParseError("message nested too deeply", where) from None
            yield row["topic"], available, valid, msg

    def close(self) -> None:
        pass


def _floats(value: Any) -> Any:
    if isinstance(value, Decimal):
        return float(value)
    if isinstance(value, dict):
        return {k: _floats(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_floats(v) for v in value]
    return value


class PushSource:
    """Samples pushed from any live source (a ROS callback, a socket reader, a test), for
    `KnowledgeManager.monitor`:

        source = PushSource()
        run = km.monitor("always (Speed[car1] < 90)", source)  # iterate it in another thread
        source.push("topic3", 12.5, {"id": 1, "spd": 61.5})     # time in seconds
        source.end()

    Times are seconds (int, float, Decimal, Fraction or decimal text), exact as written; the
    valid time is `time`, the available time `available` (default: the same)."""

    name = "<push>"
    _END = object()

    def __init__(self) -> None:
        self._queue: queue.Queue[Any] = queue.Queue()
        self.first: int | None = None  # the first sample's available time (ns), once taken

    def push(self, topic: str, time: Any, msg: Any, available: Any = None) -> None:
        """One sample; a bad time raises here and ends the monitor with the same error."""
        try:
            valid = to_ns(time)
            at = valid if available is None else to_ns(available, "available time")
        except DkError as exc:
            self._queue.put(exc)
            raise
        self._queue.put((topic, at, valid, msg))

    def end(self) -> None:
        """No more samples: the monitor settles what is open and stops."""
        self._queue.put(self._END)

    def close(self) -> None:
        pass

    def types(self) -> dict[str, str]:
        return {}

    def check_field(self, topic: str, field: str) -> str | None:
        return None

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        return None

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def first_record(self) -> int | None:
        return self.first

    def last_record(self) -> int | None:
        return None

    def messages(self, wanted: Wanted) -> Iterator[Message]:
        read = dict_reader(self.name, wanted)
        while (item := self._queue.get()) is not self._END:
            if isinstance(item, DkError):
                raise item
            topic, available, valid, msg = item
            if self.first is None:
                self.first = available
            if topic in wanted:
                yield topic, available, valid, read(topic, valid, msg)


def open_source(path: Path, msg_files: Sequence[Path] = (), typestore: str | None = None) -> Source:
    """The source for `path`; a recording whose index or metadata rosbags cannot read is read
    sequentially up to its damage (stream/damaged.py)."""
    if path.suffix == ".jsonl" or path.suffix == ".json" or str(path) == "-":
        return JsonlSource(path)
    found = kind_of(path) if path.exists() else None
    if found is not None:
        check_magic(*found)
    if (
        found is not None
        and found[0] == "db3"
        and declared_size(found[1]) > found[1].stat().st_size
    ):  # SQLite would read a cut file without a word
        return SequentialSource(
            found[1],
            "db3",
            msg_files,
            "the file is shorter than its header says (cut off)",
            typestore,
        )
    try:
        return RosbagSource(path, msg_files, typestore)
    except DkError as exc:
        if found is None:
            raise
        why = str(exc).removeprefix(f"{path}: ")
        return SequentialSource(found[1], found[0], msg_files, why, typestore)
