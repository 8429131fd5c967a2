"""An indexed MCAP file read chunk by chunk, records unpacked with one `struct` call each.

rosbags reads MCAP through a BytesIO per record and a named tuple per message: ~2 µs a
message, most of what a monitor spends on a recording.  Here a chunk (found through the
summary's chunk index) is read and decompressed whole, and its message records are walked by
offset, keeping only the channels asked for: ~0.4 µs a message.  The order is rosbags': by
record time, chunks in file order on ties, each chunk's messages sorted (stably) when written
out of order, and overlapping chunks merged.  A file without a summary or chunk index is left
to rosbags (`open_indexed` → None).

Damage loses only what is damaged.  A chunk is inflated within bounds (stream/chunks.py); one
failing its CRC is lost whole (where the damage lies in it cannot be told), and one that cannot
be verified (no CRC, cut off, not inflating) gives its records up to the first that breaks (one
running past the chunk, of no kind a chunk holds, a message stamped outside the chunk's span).
The chunks after a damaged one are read all the same; `IndexedMcap.damaged` says what was lost.
"""

from __future__ import annotations

import heapq
import itertools
import os
import struct
import zlib
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from operator import itemgetter
from pathlib import Path
from typing import Any, BinaryIO

from ..inputs.files import max_input
from .chunks import inflate_prefix
from .units import seconds_text

Message = tuple[int, int, bytes]  # channel id, record time (ns), serialised message
BATCH = 4096

_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, CRC (after op, length)
_RECORD = struct.Struct("<BQ")  # opcode, content length
_HEAD = struct.Struct("<BQHIQ")  # a message record's opcode, length, channel id, sequence, log
# time (then publish time, data)


@dataclass(frozen=True, slots=True)
class ChunkDamage:
    """A chunk read in part or not at all: where it is, its span (ns, as the index says),
    what broke, and the record time of the last message read from it (None: none was)."""

    offset: int
    start: int
    end: int
    why: str
    read_until: int | None

    def __str__(self) -> str:
        kept = (
            "nothing of it was read"
            if self.read_until is None
            else f"read up to {seconds_text(self.read_until)} s, the rest of it lost"
        )
        return (
            f"the chunk at byte {self.offset:,} ({seconds_text(self.start)} to "
            f"{seconds_text(self.end)} s) {self.why}: {kept}"
        )


@dataclass(frozen=True, slots=True)
class Survey:
    """What an indexed MCAP file's chunks hold, read from them rather than taken from its
    index: messages a topic, the span of their record times (None: no message), the damage."""

    counts: dict[str, int]
    start: int | None
    end: int | None
    damaged: tuple[ChunkDamage, ...]


@dataclass(frozen=True, slots=True)
class _Chunk:
    start: int
    end: int
    offset: int
    length: int


class IndexedMcap:
    """The chunks and channels of an MCAP file with a summary (see `open_indexed`)."""

    def __init__(
        self, handle: BinaryIO, chunks: list[_Chunk], channels: dict[int, tuple[str, str]]
    ) -> None:
        self._file, self._chunks = handle, chunks
        self.size = os.fstat(handle.fileno()).st_size
        self.channels = channels  # id → (topic, message encoding)
        self.damaged: list[ChunkDamage] = []  # of the last `batches`, in the order met

    def close(self) -> None:
        self._file.close()

    def batches(self, channels: Iterable[int]) -> Iterator[Iterable[Message]]:
        """(channel, record time, data) of the given channels in rosbags' order, a chunk (or
        BATCH messages of overlapping chunks) at a time; a damaged chunk gives the messages
        before its damage, and is listed in `damaged`."""
        wanted = frozenset(channels)
        self.damaged = []
        for run in _runs(self._chunks):
            if len(run) == 1:
                yield self._chunk(run[0], wanted)
                continue
            merged = heapq.merge(*(self._lazy(c, wanted) for c in run), key=itemgetter(1))
            while batch := list(itertools.islice(merged, BATCH)):
                yield batch

    def survey(self, channels: Iterable[int]) -> Survey:
        """Every chunk read (`dkreason info`): what they hold of `channels`, what was lost."""
        counts: Counter[int] = Counter()
        start = end = None
        for batch in self.batches(channels):
            rows = list(batch)  # in time order
            if rows:
                counts.update(map(itemgetter(0), rows))
                start = rows[0][1] if start is None else start
                end = rows[-1][1]
        topics: Counter[str] = Counter()
        for channel, n in counts.items():
            topics[self.channels[channel][0]] += n
        return Survey(dict(topics), start, end, tuple(self.damaged))

    def damage(self) -> str | None:
        """What the last `batches` lost, in one line (None: nothing)."""
        if not self.damaged:
            return None
        shown = "; ".join(str(d) for d in self.damaged[:3])
        more = f"; and {len(self.damaged) - 3} more" if len(self.damaged) > 3 else ""
        return f"{len(self.damaged)} of its {len(self._chunks)} chunks damaged: {shown}{more}"

    def _lazy(self, chunk: _Chunk, wanted: frozenset[int]) -> Iterator[Message]:
        yield from self._chunk(chunk, wanted)  # read when the merge first asks

    def _chunk(self, chunk: _Chunk, wanted: frozenset[int]) -> Iterable[Message]:
        """The chunk's wanted messages; of a damaged chunk, those before the damage (and the
        damage in `damaged`)."""
        data, crc, broken = self._records(chunk)
        messages, sound = _messages(data, wanted, chunk.start, chunk.end)
        if sound and broken is None and not (crc and zlib.crc32(data) != crc):
            return messages
        length, why = sound_prefix(data, crc, broken, chunk.start, chunk.end)
        kept = list(_messages(data[:length], wanted, chunk.start, chunk.end)[0])
        if why is not None:
            last = max((t for _, t, _ in kept), default=None)
            self.damaged.append(ChunkDamage(chunk.offset, chunk.start, chunk.end, why, last))
        return kept

    def _records(self, chunk: _Chunk) -> tuple[bytes, int, str | None]:
        """The chunk's records inflated, its CRC, and why they are only a prefix of them (or
        none at all); None: they are whole."""
        limit = max_input()
        if chunk.offset < 0 or chunk.offset + chunk.length > self.size:
            return b"", 0, f"lies past the end of the file ({self.size:,} bytes)"
        if chunk.length > limit:
            big = f"is {chunk.length:,} bytes, more than the {limit:,} one input may hold"
            return b"", 0, f"{big} (raise DKREASON_MAX_INPUT to read it)"
        self._file.seek(chunk.offset)
        record = self._file.read(chunk.length)
        if len(record) != chunk.length:
            return b"", 0, "is cut off"
        op, length = _RECORD.unpack_from(record) if len(record) >= 49 else (0, 0)
        if op != 0x06 or length + 9 != len(record):
            return b"", 0, "is not where the index says"
        _, _, size, crc = _CHUNK_HEAD.unpack_from(record, 9)
        n = int.from_bytes(record[37:41], "little")
        compression = record[41 : 41 + n].decode("utf-8", "replace")
        compressed = int.from_bytes(record[41 + n : 49 + n], "little")
        if 49 + n + compressed != len(record):
            return b"", 0, "has a header that disagrees with its length"
        data, broken = inflate_prefix(compression, record[49 + n :], size)
        return data, crc, broken


def sound_prefix(
    data: bytes, crc: int, broken: str | None, start: int, end: int
) -> tuple[int, str | None]:
    """How many bytes of a chunk's records (inflated, maybe only in part) are sound, and what
    ends them there (None: all are).  A chunk with a CRC is verified by it: when whole and
    failing it, nothing of it is sound (which records the damage reached cannot be told).
    Records that cannot be verified (no CRC; cut off or not inflating: `broken`) are sound up
    to the first that breaks (`_good_prefix`), the damage only found where the records break."""
    if broken is None and crc and zlib.crc32(data) != crc:
        return 0, "fails its checksum"
    length, bad = _good_prefix(data, start, end)
    return length, broken or bad


def _good_prefix(data: bytes, start: int, end: int) -> tuple[int, str | None]:
    """How many bytes of a chunk's records are whole and sound, and what ends them there
    (None: they all are): a record of no kind a chunk holds, one running past the chunk's
    end, a message shorter than its header or stamped outside the chunk's span."""
    pos, size = 0, len(data)
    while pos < size:
        if pos + 9 > size:
            return pos, "ends in the middle of a record"
        op, length = _RECORD.unpack_from(data, pos)
        if op not in (0x03, 0x04, 0x05):
            return pos, f"holds a record of no kind a chunk holds (opcode {op:#04x})"
        if pos + 9 + length > size:
            return pos, "holds a record running past its end"
        if op == 0x05:
            if length < 22:
                return pos, "holds a message record shorter than its own header"
            t = int.from_bytes(data[pos + 15 : pos + 23], "little")
            if not start <= t <= end:
                return pos, f"holds a message stamped {seconds_text(t)} s, outside its span"
        pos += 9 + length
    return pos, None


def _messages(
    data: bytes, wanted: frozenset[int], start: int, end: int
) -> tuple[Iterable[Message], bool]:
    """The wanted message records of one chunk's records, by time (stable), and whether the
    records were sound throughout (else `_good_prefix` finds where they stop being).  Kept as
    three lists zipped, not a tuple a message: a chunk's thousands of messages are then no
    work for the cyclic GC (which a list of tuples as long set off every 700 and promoted)."""
    channels: list[int] = []
    times: list[int] = []
    raws: list[bytes] = []
    add_channel, add_time, add_raw = channels.append, times.append, raws.append
    record, head = _RECORD.unpack_from, _HEAD.unpack_from
    pos, size, ordered, last = 0, len(data), True, -1
    whole = size - _HEAD.size  # a record starting at or before this has room for a head
    while pos < size:
        if pos <= whole:  # a message's opcode, length, channel and log time in one call
            op, length, channel, _, t = head(data, pos)
        elif pos + 9 <= size:
            (op, length), channel = record(data, pos), None
        else:
            break
        if op == 0x05:
            if length < 22:
                break
            if channel in wanted:
                if t < last:
                    ordered = False
                last = t
                add_channel(channel)
                add_time(t)
                add_raw(data[pos + 31 : pos + 9 + length])
        elif op != 0x03 and op != 0x04:
            break
        pos += 9 + length
    sound = pos == size
    if sound and times:  # a time outside the chunk's span is a corrupt record
        first, final = (times[0], times[-1]) if ordered else (min(times), max(times))
        sound = start <= first and final <= end
    out = zip(channels, times, raws, strict=True)
    return (out if ordered else sorted(out, key=itemgetter(1))), sound


def _runs(chunks: list[_Chunk]) -> Iterator[list[_Chunk]]:
    """Chunks in time order, each group whose spans overlap merged, in file order.  Chunks
    that only touch (one ends when the next starts) need no merge when the earlier one comes
    first in the file too: a merge would give its messages of that instant first anyway."""
    run: list[_Chunk] = []
    end = last = -1
    for chunk in sorted(chunks, key=lambda c: (c.start, c.offset)):
        if run and (chunk.start > end or (chunk.start == end and chunk.offset > last)):
            yield sorted(run, key=lambda c: c.offset)
            run = []
        run.append(chunk)
        end = max(end, chunk.end) if len(run) > 1 else chunk.end
        last = max(last, chunk.offset) if len(run) > 1 else chunk.offset
    if run:
        yield sorted(run, key=lambda c: c.offset)


def open_indexed(path: Path) -> IndexedMcap | None:
    """The file's chunk index and channels, or None when it has no summary to read them
    from (rosbags then reads it as it can)."""
    from mcap.reader import make_reader

    handle = open(path, "rb")  # noqa: SIM115 - kept open by the IndexedMcap
    try:
        summary: Any = make_reader(handle).get_summary()
    except Exception:
        summary = None
    if summary is None or not summary.chunk_indexes:
        handle.close()
        return None
    chunks = [
        _Chunk(c.message_start_time, c.message_end_time, c.chunk_start_offset, c.chunk_length)
        for c in summary.chunk_indexes
    ]
    channels = {c.id: (c.topic, c.message_encoding) for c in summary.channels.values()}
    return IndexedMcap(handle, chunks, channels)
