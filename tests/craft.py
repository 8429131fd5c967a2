"""MCAP files built record by record, each chunk's header as a test gives it (the size it
declares, its compression, its CRC, its compressed bytes), for the tests of bombs and damage;
and hypothesis strategies over such headers (tests/test_mcapread.py, test_damaged.py,
test_fuzz.py).  One channel, /a, carries std_msgs/msg/Float64; a message's value is read back
as `msg.data`."""

from __future__ import annotations

import bz2
import functools
import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from hypothesis import strategies as st

FLOAT64 = "float64 data\n"
MAGIC = b"\x89MCAP0\r\n"
Row = tuple[int, float]  # record time (ns), value


@dataclass(frozen=True)
class Chunk:
    """A chunk of messages on /a; a header field left None is written true."""

    rows: tuple[Row, ...]
    compression: str = ""
    declared: int | None = None  # the uncompressed size it declares
    crc: int | None = None  # 0: none
    data: bytes | None = None  # its compressed bytes


def records(rows: Sequence[Row]) -> bytes:
    """The message records of `rows`, as a chunk holds them."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import Message

    out: Any = RecordBuilder()  # mcap's builder is untyped
    for n, (t, v) in enumerate(rows):
        data = b"\x00\x01\x00\x00" + struct.pack("<d", v)
        Message(channel_id=1, log_time=t, data=data, publish_time=t, sequence=n).write(out)
    return bytes(out.end())


def compress(compression: str, data: bytes) -> bytes:
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdCompressor().compress(data)
    if compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.compress(data))
    if compression == "bz2":
        return bz2.compress(data)
    return data


def write(path: Path, chunks: Sequence[Chunk], summary: bool = True) -> list[int]:
    """An MCAP file of `chunks` (with a summary indexing them, or none); each chunk's offset."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import (
        Channel,
        ChunkIndex,
        DataEnd,
        Footer,
        Header,
        Schema,
        Statistics,
    )
    from mcap.records import Chunk as ChunkRecord

    out, b = bytearray(MAGIC), cast(Any, RecordBuilder())  # mcap's builder is untyped
    schema = Schema(id=1, name="std_msgs/msg/Float64", encoding="ros2msg", data=FLOAT64.encode())
    channel = Channel(id=1, topic="/a", message_encoding="cdr", metadata={}, schema_id=1)
    for record in (Header(profile="ros2", library="test"), schema, channel):
        record.write(b)
    out += b.end()
    offsets, indexes = [], []
    for chunk in chunks:
        raw = records(chunk.rows)
        data = compress(chunk.compression, raw) if chunk.data is None else chunk.data
        times = [t for t, _ in chunk.rows] or [0]
        header = ChunkRecord(
            compression=chunk.compression,
            data=data,
            message_start_time=min(times),
            message_end_time=max(times),
            uncompressed_crc=zlib.crc32(raw) if chunk.crc is None else chunk.crc,
            uncompressed_size=len(raw) if chunk.declared is None else chunk.declared,
        )
        offsets.append(len(out))
        header.write(b)
        record = b.end()
        out += record
        indexes.append(
            ChunkIndex(
                message_start_time=min(times),
                message_end_time=max(times),
                chunk_start_offset=offsets[-1],
                chunk_length=len(record),
                message_index_offsets={},
                message_index_length=0,
                compression=chunk.compression,
                compressed_size=len(data),
                uncompressed_size=header.uncompressed_size,
            )
        )
    DataEnd(data_section_crc=0).write(b)
    out += b.end()
    start = len(out) if summary else 0
    if summary:
        rows = [r for c in chunks for r in c.rows] or [(0, 0.0)]
        statistics = Statistics(
            attachment_count=0,
            channel_count=1,
            channel_message_counts={1: sum(len(c.rows) for c in chunks)},
            chunk_count=len(chunks),
            message_count=sum(len(c.rows) for c in chunks),
            message_end_time=max(t for t, _ in rows),
            message_start_time=min(t for t, _ in rows),
            metadata_count=0,
            schema_count=1,
        )
        for summarised in (schema, channel, *indexes, statistics):
            summarised.write(b)
    Footer(summary_start=start, summary_offset_start=0, summary_crc=0).write(b)
    out += b.end() + MAGIC
    path.write_bytes(bytes(out))
    return offsets


def rows(first: int, n: int) -> tuple[Row, ...]:
    """n messages a second apart from second `first`, each valued its second."""
    return tuple(((first + k) * 10**9, float(first + k)) for k in range(n))


def read(path: Path) -> tuple[list[float], str | None]:
    """The values read from /a, and the one-line error that ended the reading (None: none)."""
    from dkreason.errors import DkError
    from dkreason.stream.sources import open_source

    values: list[float] = []
    try:
        source = open_source(path)
    except DkError as exc:
        return values, str(exc)
    try:
        for _, _, _, (v,) in source.messages({"/a": ["msg.data"]}):
            values.append(v)
    except DkError as exc:
        return values, str(exc)
    finally:
        source.close()
    return values, None


@functools.cache
def zstd_bomb() -> bytes:
    """65 KB of zstd that inflates to 2 GB of zeros, and says so in its frame."""
    import zstandard

    compressor = zstandard.ZstdCompressor(level=1).compressobj(size=2**31)
    zeros = bytes(1 << 22)
    return b"".join([*(compressor.compress(zeros) for _ in range(2**31 >> 22)), compressor.flush()])


@functools.cache
def lz4_bomb() -> bytes:
    """1 MB of lz4 that inflates to 256 MiB of zeros."""
    import lz4.frame

    compressor = lz4.frame.LZ4FrameCompressor()
    zeros = bytes(1 << 22)
    return bytes(
        b"".join(
            [
                compressor.begin(),
                *(compressor.compress(zeros) for _ in range(64)),
                compressor.flush(),
            ]
        )
    )


# ---- strategies ---------------------------------------------------------------------------

COMPRESSIONS = ("", "zstd", "lz4")


@st.composite
def chunk_headers(draw: st.DrawFn, rows_: tuple[Row, ...]) -> Chunk:
    """A chunk of `rows_` whose header is true, or lies: a declared size off by a little or
    by up to 2**64, a wrong or absent CRC, another compression named than used (or one that
    does not exist), compressed bytes cut short."""
    compression = draw(st.sampled_from(COMPRESSIONS))
    raw = records(rows_)
    data = compress(compression, raw)
    named = draw(st.sampled_from([compression, *COMPRESSIONS, "bz2", "gzip", "zstd\x00"]))
    declared = draw(
        st.one_of(
            st.none(),
            st.integers(-16, 16).map(lambda d: max(0, len(raw) + d)),
            st.integers(0, 2**64 - 1),
        )
    )
    crc = draw(st.sampled_from([None, 0, None]) | st.integers(1, 2**32 - 1))
    cut = draw(st.one_of(st.none(), st.integers(0, max(0, len(data) - 1))))
    return Chunk(rows_, named, declared, crc, data if cut is None else data[:cut])


def readable_rows(chunk: Chunk) -> tuple[Row, ...] | None:
    """The rows a reader must give from the chunk and go on: all of them when its header is
    true, or the ones its bytes hold when nothing betrays a cut (an uncompressed chunk cut at a
    record boundary, with no size or CRC that disagrees: an empty chunk is a valid chunk);
    None when the chunk must end the reading."""
    if true_header(chunk):
        return chunk.rows
    if chunk.compression != "" or chunk.data is None:
        return None
    raw = records(chunk.rows)  # what a header field left None says
    if (len(raw) if chunk.declared is None else chunk.declared) != len(chunk.data):
        return None
    if (zlib.crc32(raw) if chunk.crc is None else chunk.crc) not in (0, zlib.crc32(chunk.data)):
        return None
    kept = [k for k in range(len(chunk.rows)) if records(chunk.rows[:k]) == chunk.data]
    return chunk.rows[: kept[0]] if kept else None


def true_header(chunk: Chunk) -> bool:
    """Whether the chunk's header tells the truth about its bytes (it must then read whole)."""
    raw = records(chunk.rows)
    return (
        chunk.declared in (None, len(raw))
        and chunk.crc in (None, 0, zlib.crc32(raw))
        and chunk.data is not None
        and chunk.compression in COMPRESSIONS
        and chunk.data == compress(chunk.compression, raw)
    )
