"""An indexed MCAP file read chunk by chunk, records unpacked with one `struct` call each.

rosbags reads MCAP through a BytesIO per record and a named tuple per message: ~2 µs a
message, most of what a monitor spends on a recording.  Here a chunk (found through the
summary's chunk index) is read and decompressed whole, and its message records are walked by
offset, keeping only the channels asked for: ~0.4 µs a message.  The order is rosbags': by
record time, chunks in file order on ties, each chunk's messages sorted (stably) when written
out of order, and overlapping chunks merged.  A file this reader cannot take as it is (no
summary or chunk index, an unknown compression) is left to rosbags (`open_indexed` → None);
damage found while reading raises `McapDamage` with what broke.
"""

from __future__ import annotations

import heapq
import itertools
import os
import struct
import zlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from operator import itemgetter
from pathlib import Path
from typing import Any, BinaryIO

Message = tuple[int, int, bytes]  # channel id, record time (ns), serialised message
BATCH = 4096

_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, CRC (after op, length)
_RECORD = struct.Struct("<BQ")  # opcode, content length
_HEAD = struct.Struct("<BQHIQ")  # a message record's opcode, length, channel id, sequence, log
# time (then publish time, data)


class McapDamage(Exception):
    """What broke in a chunk (a torn or corrupt chunk, a record past its end)."""


def _decompressor(compression: str) -> Callable[[bytes, int], bytes] | None:
    if compression == "":
        return lambda data, _: data
    if compression == "zstd":
        import zstandard

        return lambda data, size: zstandard.ZstdDecompressor().decompress(
            data, max_output_size=size
        )
    if compression == "lz4":
        import lz4.frame

        return lambda data, _: bytes(lz4.frame.decompress(data))
    return None


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

    def close(self) -> None:
        self._file.close()

    def batches(self, channels: Iterable[int]) -> Iterator[Iterable[Message]]:
        """(channel, record time, data) of the given channels in rosbags' order, a chunk (or
        BATCH messages of overlapping chunks) at a time."""
        wanted = frozenset(channels)
        for run in _runs(self._chunks):
            if len(run) == 1:
                yield self._chunk(run[0], wanted)
                continue
            merged = heapq.merge(*(self._lazy(c, wanted) for c in run), key=itemgetter(1))
            while batch := list(itertools.islice(merged, BATCH)):
                yield batch

    def _lazy(self, chunk: _Chunk, wanted: frozenset[int]) -> Iterator[Message]:
        yield from self._chunk(chunk, wanted)  # read when the merge first asks

    def _chunk(self, chunk: _Chunk, wanted: frozenset[int]) -> Iterable[Message]:
        handle = self._file
        if chunk.offset < 0 or chunk.offset + chunk.length > self.size:
            raise McapDamage(
                f"the index points past the end of the file ({self.size:,} "
                f"bytes) for a chunk at byte {chunk.offset:,}"
            )
        handle.seek(chunk.offset)
        record = handle.read(chunk.length)
        if len(record) != chunk.length:
            raise McapDamage(f"the chunk at byte {chunk.offset:,} is cut off")
        op, length = _RECORD.unpack_from(record)
        if op != 0x06 or length + 9 != chunk.length:
            raise McapDamage(f"no chunk at byte {chunk.offset:,}, where the index says")
        _, _, size, crc = _CHUNK_HEAD.unpack_from(record, 9)
        n = int.from_bytes(record[37:41], "little")
        compression = record[41 : 41 + n].decode("utf-8", "replace")
        compressed = int.from_bytes(record[41 + n : 49 + n], "little")
        inflate = _decompressor(compression)
        if inflate is None:
            raise McapDamage(f"unknown chunk compression {compression!r}")
        try:
            data = inflate(record[49 + n : 49 + n + compressed], size)
        except Exception as exc:
            raise McapDamage(
                f"the chunk at byte {chunk.offset:,} does not decompress ({exc})"
            ) from None
        if len(data) != size or (crc and zlib.crc32(data) != crc):
            raise McapDamage(f"the chunk at byte {chunk.offset:,} fails its checksum")
        return _messages(data, wanted)


def _messages(data: bytes, wanted: frozenset[int]) -> Iterable[Message]:
    """The wanted message records of one chunk's records, by time (stable).  Kept as three
    lists zipped, not a tuple a message: a chunk's thousands of messages are then no work for
    the cyclic GC (which a list of tuples as long set off every 700 and promoted)."""
    channels: list[int] = []
    times: list[int] = []
    raws: list[bytes] = []
    add_channel, add_time, add_raw = channels.append, times.append, raws.append
    record, head = _RECORD.unpack_from, _HEAD.unpack_from
    pos, end, ordered, last = 0, len(data), True, -1
    whole = end - _HEAD.size  # a record starting at or before this has room for a head
    while pos < end:
        if pos <= whole:  # a message's opcode, length, channel and log time in one call
            op, length, channel, _, t = head(data, pos)
        else:
            (op, length), channel = record(data, pos), None
        if op == 0x05:
            if length < 22:
                raise McapDamage("a message record shorter than its own header")
            if channel in wanted:
                if t < last:
                    ordered = False
                last = t
                add_channel(channel)
                add_time(t)
                add_raw(data[pos + 31 : pos + 9 + length])
        pos += 9 + length
    if pos != end:
        raise McapDamage("a record runs past the end of its chunk")
    out = zip(channels, times, raws, strict=True)
    return out if ordered else sorted(out, key=itemgetter(1))


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
    if (
        summary is None
        or not summary.chunk_indexes
        or any(_decompressor(c.compression) is None for c in summary.chunk_indexes)
    ):
        handle.close()
        return None
    chunks = [
        _Chunk(c.message_start_time, c.message_end_time, c.chunk_start_offset, c.chunk_length)
        for c in summary.chunk_indexes
    ]
    channels = {c.id: (c.topic, c.message_encoding) for c in summary.channels.values()}
    return IndexedMcap(handle, chunks, channels)
