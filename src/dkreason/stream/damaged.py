"""Recordings whose index or metadata is damaged or missing, read front to back up to the damage.

A recording cut off mid-write (a robot that lost power, a copy that stopped) has intact
messages before the cut; rosbags refuses such a file whole because it reads the index first.
Here each format is read record by record — MCAP records, ROS 1 bag records and chunks, the
rows of a rosbag2 sqlite3 file — learning topics and message definitions as they come; at the
damage, `DamagedRecording` says how many messages were read and where the file broke, after
the monitor has used every message before it.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import sqlite3
import struct
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO, Literal

from ..errors import DkError
from ..inputs.files import max_input, regular, shown
from . import fields
from .chunks import inflate_prefix
from .mcapread import sound_prefix
from .typestore import load_typestore, msg_types, ros_reader
from .units import NS

Kind = Literal["mcap", "ros1", "db3"]
# what a format yields: ("type", name, definition) | ("channel", id, topic, msgtype)
#                     | ("message", channel id, record time in ns, raw bytes)
Item = tuple[Any, ...]


class DamagedRecording(DkError):
    """The recording broke after some messages; the ones before were monitored."""


class _Cut(Exception):
    """Where and why a format's reader stopped."""


def kind_of(path: Path) -> tuple[Kind, Path] | None:
    """The format to read `path` in sequentially, and the file (a bag folder's storage file)."""
    if path.is_dir():
        files = sorted([*path.glob("*.mcap"), *path.glob("*.db3")])
        if len(files) != 1:
            return None
        path = files[0]
    name = path.name.lower()
    if name.endswith(".mcap"):
        return "mcap", path
    if name.endswith(".db3"):
        return "db3", path
    if name.endswith((".bag", ".bag.active")):
        return "ros1", path
    return None


class SequentialSource:
    """A Source over a damaged or unindexed recording (see the module docstring)."""

    def __init__(
        self,
        path: Path,
        kind: Kind,
        msg_files: Sequence[Path],
        why: str,
        typestore: str | None = None,
    ) -> None:
        self.name, self.path, self.kind = str(path), path, kind
        self.note = f"{path}: {why}; reading it sequentially up to the damage"
        given = msg_types(msg_files)
        self.store = load_typestore(given, kind == "ros1", typestore)
        self.channels: dict[Any, tuple[str, str]] = {}  # id → topic, msgtype
        self.first: int | None = None  # the first message's record time, once read
        self._known: set[str] = set(given)  # --msg replaces the recording's definition
        try:
            for item in _READERS[kind](path):
                if item[0] != "message":
                    self._learn(item)
        except _Cut as cut:
            if not self.channels:
                raise DkError(f"{path}: not a readable ROS recording ({cut})") from None

    def _learn(self, item: Item) -> None:
        from rosbags.typesys import get_types_from_msg

        if item[0] == "type" and item[1] not in self._known and item[2]:
            self._known.add(item[1])
            try:
                self.store.register(get_types_from_msg(item[2], item[1]))
            except Exception as exc:  # rosbags raises several kinds for bad definitions
                raise DkError(
                    f"{self.name}: message definition {item[1]} unreadable ({str(exc)[:200]})"
                ) from None
        elif item[0] == "channel":
            self.channels[item[1]] = (item[2], item[3])

    def types(self) -> dict[str, str]:
        return dict(self.channels.values())

    def first_record(self) -> int | None:
        return self.first

    def last_record(self) -> int | None:
        return None

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        msgtype = self.types().get(topic)
        if msgtype is None or msgtype not in self.store.fielddefs:
            return None
        return fields.kind(self.store.fielddefs, msgtype, field)

    def check_field(self, topic: str, field: str) -> str | None:
        msgtype = self.types().get(topic)
        if msgtype is None:
            return None
        if msgtype not in self.store.fielddefs:
            return f"message type {msgtype} has no definition (give --msg)"
        return fields.check(self.store.fielddefs, msgtype, field)

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def close(self) -> None:
        pass

    def messages(self, wanted: dict[str, list[str]]) -> Iterator[tuple[str, int, int, Any]]:
        deserialize = (
            self.store.deserialize_ros1 if self.kind == "ros1" else self.store.deserialize_cdr
        )
        readers: dict[Any, tuple[Any, bool]] = {}
        n = 0
        try:
            for item in _READERS[self.kind](self.path):
                if item[0] != "message":
                    self._learn(item)
                    continue
                _, channel, t_ns, raw = item
                if self.first is None:
                    self.first = t_ns
                topic, msgtype = self.channels.get(channel, ("", ""))
                if topic not in wanted:
                    continue
                if channel not in readers:
                    readers[channel] = ros_reader(
                        self.store.fielddefs,
                        msgtype,
                        wanted[topic],
                        self.kind == "ros1",
                        deserialize,
                    )
                read, stamped = readers[channel]
                try:
                    values = read(raw)
                except Exception as exc:
                    raise _Cut(
                        f"message {n + 1} on {topic} does not decode as {msgtype}: {str(exc)[:100]}"
                    ) from None
                n += 1
                yield topic, t_ns, values[-2] * NS + values[-1] if stamped else t_ns, values
        except _Cut as cut:
            raise DamagedRecording(
                f"{self.name}: damaged recording: {cut}; {n} messages "
                f"before it were monitored, the rest is lost"
            ) from None


# ---- MCAP ---------------------------------------------------------------------------------
# Read here, not with mcap's StreamReader, so that a chunk cut off or damaged mid-way still
# gives its sound records (recorders write a chunk of ~1 MB at a time).

MAGIC: dict[Kind, bytes] = {
    "mcap": b"\x89MCAP0\r\n",
    "ros1": b"#ROSBAG V2.0\n",
    "db3": b"SQLite format 3\0",
}
_NAMES: dict[Kind, str] = {
    "mcap": "an MCAP file",
    "ros1": "a ROS 1 bag (format 2.0)",
    "db3": "a rosbag2 sqlite3 file",
}


def check_magic(kind: Kind, path: Path) -> None:
    """A DkError unless `path` begins as a recording of `kind` does: a file of anything else
    (a gigabyte of zeros named `.bag`) is refused from its first bytes, before any reader
    reads it to its end looking for a line or a record."""
    regular(path)
    try:
        with path.open("rb") as handle:
            begins = handle.read(len(MAGIC[kind]))
    except OSError as exc:
        raise DkError(f"{shown(path)}: cannot read ({exc.strerror})") from None
    if begins != MAGIC[kind]:
        raise DkError(
            f"{shown(path)}: not a readable ROS recording (it does not begin as "
            f"{_NAMES[kind]} does)"
        )


_SMALL = 1 << 20  # a read this small is not held to the limit (read per record otherwise)


def _take(data: BinaryIO, n: int, size: int) -> bytes:
    """n bytes of `data` (a stream of `size` bytes; fewer at its end), never asking it for
    more than it holds (a file's read allocates what it is asked for first), nor, past
    _SMALL, for more than one input may hold."""
    n = min(n, size - data.tell())
    if n > _SMALL and n > (limit := max_input()):
        raise _Cut(
            f"a record of more than the {limit:,} bytes one input may hold "
            f"(raise DKREASON_MAX_INPUT to read it)"
        )
    return data.read(n)


class _Bytes:
    """A cursor over one record's content; reading past the end raises _Cut."""

    def __init__(self, data: bytes | memoryview) -> None:
        self.data, self.pos = memoryview(data), 0

    def take(self, n: int) -> memoryview:
        if self.pos + n > len(self.data):
            raise _Cut("a record ends early")
        self.pos += n
        return self.data[self.pos - n : self.pos]

    def u16(self) -> int:
        return int.from_bytes(self.take(2), "little")

    def u32(self) -> int:
        return int.from_bytes(self.take(4), "little")

    def u64(self) -> int:
        return int.from_bytes(self.take(8), "little")

    def text(self) -> str:
        return bytes(self.take(self.u32())).decode("utf-8", "replace")


def _mcap_records(handle: BinaryIO, size: int) -> Iterator[tuple[int, bytes | memoryview]]:
    """(opcode, content) of each complete record of the file after its magic; raises _Cut at
    a torn one, after the sound records of a torn chunk."""
    while handle.tell() < size:
        head = _take(handle, 9, size)
        if len(head) < 9:
            raise _Cut("the file ends in the middle of a record")
        op, length = head[0], int.from_bytes(head[1:], "little")
        if op == 0x00:  # no record has it (zeros where records should be)
            raise _Cut("a record of no kind (opcode 0x00)")
        content = _take(handle, length, size)
        if len(content) < length:
            if op == 0x06:  # a chunk: its sound records are still good
                with contextlib.suppress(_Cut):
                    yield from _mcap_chunk(content)
            raise _Cut("the file ends in the middle of a record")
        if op == 0x02:  # the footer: only the closing magic follows
            return
        yield op, content


def _chunk_records(data: memoryview) -> Iterator[tuple[int, memoryview]]:
    """(opcode, content) of each record of a chunk's sound records."""
    pos = 0
    while pos < len(data):
        size = int.from_bytes(data[pos + 1 : pos + 9], "little")
        yield data[pos], data[pos + 9 : pos + 9 + size]
        pos += 9 + size


def _mcap_chunk(content: bytes | memoryview) -> Iterator[tuple[int, memoryview]]:
    """The records of a chunk (whole or cut off) up to its damage, then _Cut saying what it
    is (stream/mcapread.py's `sound_prefix`)."""
    chunk = _Bytes(content)
    start, end, size, crc = chunk.u64(), chunk.u64(), chunk.u64(), chunk.u32()
    compression = chunk.text()
    compressed = chunk.u64()
    records, broken = inflate_prefix(
        compression, bytes(chunk.data[chunk.pos : chunk.pos + compressed]), size
    )
    length, why = sound_prefix(records, crc, broken, start, end)
    yield from _chunk_records(memoryview(records)[:length])
    if why is not None:
        raise _Cut(f"a chunk {why}")


def _mcap(path: Path) -> Iterator[Item]:
    with path.open("rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if handle.read(len(MAGIC["mcap"])) != MAGIC["mcap"]:
            raise _Cut("not an MCAP file")
        schemas: dict[int, str] = {}
        try:
            for op, content in _mcap_records(handle, size):
                items = _mcap_chunk(content) if op == 0x06 else iter([(op, content)])
                for inner, body in items:
                    yield from _mcap_item(inner, _Bytes(body), schemas)
        except _Cut as cut:
            raise _Cut(f"{cut} (byte {handle.tell():,} of {size:,})") from None
        except Exception as exc:
            raise _Cut(f"{str(exc)[:120]} (byte {handle.tell():,} of {size:,})") from None


def _mcap_item(op: int, r: _Bytes, schemas: dict[int, str]) -> Iterator[Item]:
    if op == 0x05:  # message
        channel, _, log_time, _ = r.u16(), r.u32(), r.u64(), r.u64()
        yield "message", channel, log_time, bytes(r.data[r.pos :])
    elif op == 0x03:  # schema
        id_, name, encoding = r.u16(), r.text(), r.text()
        text = bytes(r.take(r.u32())).decode("utf-8", "replace")
        if encoding == "ros2msg":
            schemas[id_] = name
            yield "type", name, text
    elif op == 0x04:  # channel
        id_, schema, topic = r.u16(), r.u16(), r.text()
        if schema in schemas:
            yield "channel", id_, topic, schemas[schema]


# ---- ROS 1 bags (format 2.0) -------------------------------------------------------------


def _fields(header: bytes) -> dict[str, bytes]:
    out, i = {}, 0
    while i + 4 <= len(header):
        (size,) = struct.unpack_from("<I", header, i)
        name, _, value = header[i + 4 : i + 4 + size].partition(b"=")
        out[name.decode("ascii", "replace")] = value
        i += 4 + size
    return out


def _ros1_records(data: BinaryIO, size: int) -> Iterator[tuple[dict[str, bytes], bytes]]:
    """(header fields, data) of each record of a bag or of a chunk's bytes (`size` of them);
    raises _Cut at a torn record, after yielding the sound records of a torn chunk."""
    while head := _take(data, 4, size):
        (hlen,) = struct.unpack("<I", head.ljust(4, b"\0"))
        header = _take(data, hlen, size)
        length = _take(data, 4, size)
        (dlen,) = struct.unpack("<I", length.ljust(4, b"\0"))
        body = _take(data, dlen, size)
        if len(head) < 4 or len(header) < hlen or len(length) < 4 or len(body) < dlen:
            fields_ = _fields(header)
            if fields_.get("op") == b"\x05":
                with contextlib.suppress(_Cut):
                    yield from _ros1_chunk(fields_, body)
            raise _Cut("the data ends in the middle of a record")
        fields_ = _fields(header)
        if "op" not in fields_:  # every record says what it is (zeros say nothing)
            raise _Cut("a record without its op field")
        yield fields_, body


def _ros1(path: Path) -> Iterator[Item]:
    with path.open("rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if handle.read(len(MAGIC["ros1"])) != MAGIC["ros1"]:
            raise _Cut("not a ROS 1 bag (format 2.0)")
        try:
            for fields_, body in _ros1_records(handle, size):
                op = fields_.get("op", b"")
                records = _ros1_chunk(fields_, body) if op == b"\x05" else [(fields_, body)]
                for inner, data in records:
                    yield from _ros1_item(inner.get("op", b""), inner, data)
        except _Cut as cut:
            raise _Cut(f"{cut} (byte {handle.tell():,} of {size:,})") from None
        except (struct.error, ValueError, OSError, KeyError, RuntimeError) as exc:
            raise _Cut(f"{exc} (byte {handle.tell():,} of {size:,})") from None


def _ros1_chunk(fields_: dict[str, bytes], body: bytes) -> Iterator[tuple[dict[str, bytes], bytes]]:
    """The records of a chunk (whole or cut off) up to its damage, then _Cut saying what it
    is."""
    compression = fields_.get("compression", b"none").decode("utf-8", "replace")
    size = fields_.get("size", b"")
    if len(size) != 4:
        raise _Cut("a chunk without its size")
    data, broken = inflate_prefix(
        "" if compression == "none" else compression, body, int.from_bytes(size, "little")
    )
    try:
        yield from _ros1_records(io.BytesIO(data), len(data))
    except _Cut:
        if broken is None:
            raise
    if broken is not None:
        raise _Cut(f"a chunk {broken}")


def _ros1_item(op: bytes, fields_: dict[str, bytes], body: bytes) -> Iterator[Item]:
    if op == b"\x07":  # connection
        conn = _fields(body)
        msgtype = conn.get("type", b"").decode()
        rostype = msgtype.replace("/", "/msg/", 1) if "/msg/" not in msgtype else msgtype
        yield "type", rostype, conn.get("message_definition", b"").decode("utf-8", "replace")
        yield "channel", struct.unpack("<I", fields_["conn"])[0], fields_["topic"].decode(), rostype
    elif op == b"\x02":  # message data
        sec, nsec = struct.unpack("<II", fields_["time"])
        yield "message", struct.unpack("<I", fields_["conn"])[0], sec * 10**9 + nsec, body


# ---- rosbag2 sqlite3 -----------------------------------------------------------------------


def declared_size(path: Path) -> int:
    """The bytes an sqlite3 file's header says it holds (0: not known)."""
    with path.open("rb") as handle:
        header = handle.read(100)
    if len(header) < 100 or not header.startswith(b"SQLite format 3\0"):
        return 0
    page = int.from_bytes(header[16:18], "big")
    return (65536 if page == 1 else page) * int.from_bytes(header[28:32], "big")


def _db3(path: Path) -> Iterator[Item]:
    """Rows in insertion order; a file cut short is read through a copy padded to the size
    its header declares (sparse), on which SQLite reads every row before the cut."""
    declared = declared_size(path)
    with tempfile.TemporaryDirectory() as tmp:
        if declared > path.stat().st_size:
            padded = Path(tmp) / path.name
            shutil.copyfile(path, padded)
            os.truncate(padded, declared)
            path = padded
        yield from _db3_rows(path)


def _db3_rows(path: Path) -> Iterator[Item]:
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro&immutable=1", uri=True)
    except sqlite3.Error as exc:
        raise _Cut(str(exc)) from None
    n = 0
    try:
        tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master")}
        if "message_definitions" in tables:
            for name, encoding, text in db.execute(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            ):
                if encoding == "ros2msg":
                    yield "type", name, text
        for id_, topic, msgtype in db.execute("SELECT id, name, type FROM topics"):
            yield "channel", id_, topic, msgtype
        for topic_id, stamp, data in db.execute(
            "SELECT topic_id, timestamp, data FROM messages ORDER BY id"
        ):
            n += 1
            yield "message", topic_id, stamp, data
    except sqlite3.Error as exc:
        raise _Cut(f"{exc} after row {n}") from None
    finally:
        db.close()


_READERS = {"mcap": _mcap, "ros1": _ros1, "db3": _db3}
