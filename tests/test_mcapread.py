"""The indexed MCAP reader gives what rosbags gives, in rosbags' order, on any chunking.

Real recordings are chunked and compressed in different ways (zstd by `ros2 bag record`'s
presets, lz4, none), messages may be written out of time order within a chunk (several
publishers, one writer) and chunks may overlap in time.  The reader's order is checked
against rosbags' own on files written that way (hypothesis).  A chunk is trusted for nothing
it says: the size it declares is bounded before anything is inflated (a zstd bomb is refused
from its header), and damage inside it loses only the rest of that chunk — the records before
it are read, and so are the chunks after it — ending the replay in one line naming it.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.stream.chunks import bound_rosbags
from dkreason.stream.damaged import DamagedRecording
from dkreason.stream.mcapread import open_indexed
from dkreason.stream.sources import RosbagSource

from .craft import Chunk, chunk_headers, lz4_bomb, read, readable_rows, records, rows, zstd_bomb
from .craft import write as craft

FLOAT64 = "float64 data\n"
TOPICS = ("/a", "/b", "/c")


def write(
    path: Path,
    messages: list[tuple[int, int, float]],
    chunk_size: int = 1024,
    compression: str = "zstd",
    json_channel: bool = False,
) -> None:
    """(channel index, record time, value) as std_msgs/msg/Float64 on /a, /b, /c."""
    from mcap.writer import CompressionType, Writer

    kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}[
        compression
    ]
    with open(path, "wb") as handle:
        writer = Writer(handle, chunk_size=chunk_size, compression=kind)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/Float64", "ros2msg", FLOAT64.encode())
        channels = [writer.register_channel(t, "cdr", schema) for t in TOPICS]
        if json_channel:
            other = writer.register_schema("note", "jsonschema", b"{}")
            channels.append(writer.register_channel("/a", "json", other))
        for n, (c, t, v) in enumerate(messages):
            data = b'{"x": 1}' if c == 3 else b"\x00\x01\x00\x00" + struct.pack("<d", v)
            writer.add_message(channels[c], log_time=t, data=data, publish_time=t, sequence=n)
        writer.finish()  # type: ignore[no-untyped-call]


def ours(path: Path) -> list[tuple[str, int, float]]:
    source = RosbagSource(path)
    try:
        return [
            (topic, t, values[0])
            for topic, t, _, values in source.messages({t: ["msg.data"] for t in TOPICS})
        ]
    finally:
        source.close()


def rosbags(path: Path) -> list[tuple[str, int, float]]:
    source = RosbagSource(path)
    try:
        return [
            (c.topic, t, source.reader.deserialize(raw, c.msgtype).data)  # type: ignore[attr-defined]
            for c, t, raw in source.reader.messages(connections=source.connections)
        ]
    finally:
        source.close()


messages = st.lists(
    st.tuples(st.integers(0, 2), st.integers(0, 40), st.floats(-1e6, 1e6)), min_size=1, max_size=120
)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(messages, st.sampled_from([60, 200, 1 << 20]), st.sampled_from(["zstd", "lz4", ""]))
def test_any_chunking_reads_as_rosbags_reads(
    tmp_path: Path, rows: list[tuple[int, int, float]], chunk_size: int, compression: str
) -> None:
    """Out-of-order times within and across chunks, equal times, overlapping chunks."""
    path = tmp_path / "r.mcap"
    write(path, rows, chunk_size, compression)
    indexed = open_indexed(path)
    assert indexed is not None  # the fast path is the one under test
    indexed.close()
    assert ours(path) == rosbags(path)


def test_channels_in_other_encodings_and_unasked_topics_are_skipped(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    write(path, [(0, 1, 1.0), (3, 2, 0.0), (1, 3, 2.0), (0, 4, 3.0)], json_channel=True)
    source = RosbagSource(path)
    assert [(topic, v) for topic, _, _, (v,) in source.messages({"/a": ["msg.data"]})] == [
        ("/a", 1.0),
        ("/a", 3.0),
    ]
    source.close()


def test_a_chunk_failing_its_checksum_is_lost_and_the_chunks_after_it_are_read(
    tmp_path: Path,
) -> None:
    """Its records all whole, the damage is in some message's data: which one cannot be told,
    so the chunk is lost whole (never a wrong value monitored), and only it."""
    path = tmp_path / "r.mcap"
    write(path, [(0, t, float(t)) for t in range(200)], chunk_size=500, compression="")
    data = bytearray(path.read_bytes())
    at = data.index(struct.pack("<d", 150.0))
    data[at : at + 8] = b"\xff" * 8  # a chunk's bytes no longer match its CRC
    path.write_bytes(bytes(data))
    seen: list[float] = []
    source = RosbagSource(path)
    with pytest.raises(DamagedRecording, match="fails its checksum") as err:
        for _, _, _, (v,) in source.messages({"/a": ["msg.data"]}):
            seen.append(v)
    source.close()
    lost = sorted({float(t) for t in range(200)} - set(seen))
    assert 150.0 in lost and lost == [float(t) for t in range(int(lost[0]), int(lost[-1]) + 1)]
    assert seen == sorted(seen) and seen[-1] == 199.0 and len(lost) < 20
    assert "\n" not in str(err.value) and f"the {len(seen)} messages read" in str(err.value)


def test_a_file_without_a_chunk_index_is_read_by_rosbags(tmp_path: Path) -> None:
    from mcap.writer import Writer

    with open(tmp_path / "plain.mcap", "wb") as handle:  # no chunk index at all
        writer = Writer(handle, use_chunking=False)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/Float64", "ros2msg", FLOAT64.encode())
        channel = writer.register_channel("/a", "cdr", schema)
        for t in range(5):
            writer.add_message(
                channel, log_time=t, data=b"\x00\x01\x00\x00" + struct.pack("<d", t), publish_time=t
            )
        writer.finish()  # type: ignore[no-untyped-call]
    assert open_indexed(tmp_path / "plain.mcap") is None
    source = RosbagSource(tmp_path / "plain.mcap")
    assert [v for _, _, _, (v,) in source.messages({"/a": ["msg.data"]})] == [
        0.0,
        1.0,
        2.0,
        3.0,
        4.0,
    ]
    source.close()


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.integers(0, 10_000), st.binary(min_size=1, max_size=8))
def test_any_corruption_gives_messages_then_one_line_never_a_traceback(
    tmp_path: Path, at: int, junk: bytes
) -> None:
    """Bytes overwritten anywhere (the index, a chunk header, a record's length): the
    messages before the damage, then a one-line DkError; never another exception or a hang."""
    path = tmp_path / "r.mcap"
    write(path, [(t % 3, t, float(t)) for t in range(150)], chunk_size=400, compression="")
    data = bytearray(path.read_bytes())
    at %= len(data)
    data[at : at + len(junk)] = junk
    path.write_bytes(bytes(data))
    try:
        source = RosbagSource(path)
    except DkError as exc:
        assert "\n" not in str(exc)
        return
    try:
        for _ in source.messages({t: ["msg.data"] for t in TOPICS}):
            pass
    except DkError as exc:
        assert "\n" not in str(exc)
    finally:
        source.close()


# ---- bombs: what a chunk declares is bounded before anything is inflated -----------------


def _spy_zstd(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, int]]:
    """zstd decompressions as (size the frame declares, output allowed), as they are asked."""
    import zstandard

    real, calls = zstandard.ZstdDecompressor, []

    class Spy:
        def __init__(self) -> None:
            self.real = real()

        def decompress(self, data: bytes, max_output_size: int = 0) -> bytes:
            calls.append((zstandard.frame_content_size(data), max_output_size))
            return self.real.decompress(data, max_output_size=max_output_size)

        def stream_reader(self, source: bytes) -> object:
            calls.append((zstandard.frame_content_size(source), -1))
            return self.real.stream_reader(source)

    monkeypatch.setattr(zstandard, "ZstdDecompressor", Spy)
    return calls


def test_a_zstd_chunk_declaring_2_gb_is_refused_from_its_header(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The issue's bomb: 65 KB of zstd that does inflate to 2 GB, and says so.  Refused before
    any decompressor is made (the bound is on the size declared, against the compressed
    size), the error telling how to raise the bound; the chunks beside it are read."""
    path = tmp_path / "bomb.mcap"
    at = craft(
        path,
        [Chunk(rows(0, 3)), Chunk(rows(3, 3), "zstd", 2**31, 0, zstd_bomb()), Chunk(rows(6, 3))],
    )[1]
    calls = _spy_zstd(monkeypatch)
    values, error = read(path)
    assert calls == []
    assert values == [0.0, 1.0, 2.0, 6.0, 7.0, 8.0]
    assert error is not None and "\n" not in error
    assert (
        f"the chunk at byte {at:,} (3 to 5 s) declares 2,147,483,648 bytes, more than 1,000 "
        f"times its 65,558 compressed bytes (raise DKREASON_MAX_CHUNK_RATIO to read it): "
        f"nothing of it was read" in error
    )
    monkeypatch.setenv("DKREASON_MAX_CHUNK_RATIO", "100000")  # then the bound on one input
    values, error = read(path)
    assert calls == [] and values == [0.0, 1.0, 2.0, 6.0, 7.0, 8.0]
    assert error is not None and "more than the 268,435,456 one input may hold (raise " in error


def test_a_zstd_frame_larger_than_its_chunk_says_is_never_inflated_past_that(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A chunk declaring 1 MB whose frame holds 2 GB: zstandard would allocate what the frame
    says; the frame's own size is checked first, and only the declared 1 MB is inflated."""
    path = tmp_path / "bomb.mcap"
    craft(path, [Chunk(rows(0, 3), "zstd", 1 << 20, 0, zstd_bomb()), Chunk(rows(3, 3))])
    calls = _spy_zstd(monkeypatch)
    values, error = read(path)
    assert values == [3.0, 4.0, 5.0]
    assert error is not None and "inflates to more than the 1,048,576 bytes it declares" in error
    assert all(declared <= allowed for declared, allowed in calls if allowed >= 0)


def test_an_lz4_frame_is_inflated_no_further_than_its_chunk_declares(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """1 MB of lz4 that inflates to 256 MiB, in a chunk declaring 1 MiB (lz4 writes as much as
    it can unless told a length), and in `dkreason info` too, which says what was lost."""
    import lz4.frame

    real, lengths = lz4.frame.LZ4FrameDecompressor, []

    class Spy:
        def __init__(self) -> None:
            self.real = real()

        def __getattr__(self, name: str) -> object:
            return getattr(self.real, name)

        def decompress(self, data: bytes, max_length: int = -1) -> bytes:
            lengths.append(max_length)
            out: bytes = self.real.decompress(data, max_length=max_length)
            return out

    monkeypatch.setattr(lz4.frame, "LZ4FrameDecompressor", Spy)
    path = tmp_path / "bomb.mcap"
    at = craft(path, [Chunk(rows(0, 3)), Chunk(rows(3, 3), "lz4", 1 << 20, 0, lz4_bomb())])[1]
    values, error = read(path)
    assert values == [0.0, 1.0, 2.0] and lengths and 0 <= max(lengths) <= (1 << 20) + 1
    assert error is not None and "inflates to more than the 1,048,576 bytes it declares" in error
    lengths.clear()
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "  /a  std_msgs/msg/Float64  3\n" in out and f"damaged: the chunk at byte {at:,}" in out
    assert 0 <= max(lengths) <= (1 << 20) + 1


def test_rosbags_inflates_within_the_same_bounds(monkeypatch: pytest.MonkeyPatch) -> None:
    """rosbags reads what dkreason's own reader does not (a ROS 1 bag, an MCAP file without a
    summary) with its own decompressors, unbounded: they are replaced by bounded ones (a ROS 1
    chunk's, told no size, by what the bounds allow its compressed size)."""
    from rosbags.rosbag1 import reader as ros1
    from rosbags.rosbag2 import storage_mcap

    bound_rosbags()
    with pytest.raises(Exception, match="declares 2,147,483,648 bytes, more than 1,000 times"):
        storage_mcap.decompress(zstd_bomb(), "zstd", 2**31, 0)
    monkeypatch.setenv("DKREASON_MAX_CHUNK_RATIO", "100")  # the lz4 bomb inflates 242 times
    with pytest.raises(Exception, match=r"a chunk \(lz4\) inflates to more than 100 times its"):
        ros1.decompressors["lz4"](lz4_bomb())


# ---- damage loses only what is damaged -----------------------------------------------------

RECORD = len(records(rows(0, 1)))  # every message record here is as long


def test_a_corrupt_record_ends_its_chunks_good_prefix_and_later_chunks_are_read(
    tmp_path: Path,
) -> None:
    """A chunk without a CRC (rosbags writes none) cannot be verified: its records are read
    up to the first that breaks.  With its CRC failing, where the damage lies cannot be told
    (it may begin before the record that breaks): the chunk is lost whole.  Either way the
    chunks after it are read."""
    good = records(rows(10, 10))
    bad = good[: 4 * RECORD] + b"\x05" + struct.pack("<Q", 10**6) + good[4 * RECORD + 9 :]
    path = tmp_path / "r.mcap"
    chunks = [Chunk(rows(0, 10)), Chunk(rows(10, 10), crc=0, data=bad), Chunk(rows(20, 10))]
    at = craft(path, chunks)[1]
    values, error = read(path)
    assert values == [float(t) for t in (*range(14), *range(20, 30))]
    assert error is not None and "\n" not in error
    assert (
        f"damaged recording: 1 of its 3 chunks damaged: the chunk at byte {at:,} (10 to 19 s) "
        f"holds a record running past its end: read up to 13 s, the rest of it lost; the 24 "
        f"messages read were monitored" in error
    )
    chunks[1] = Chunk(rows(10, 10), data=bad)  # with the CRC of its records before the damage
    craft(path, chunks)
    values, error = read(path)
    assert values == [float(t) for t in (*range(10), *range(20, 30))]
    assert error is not None and "(10 to 19 s) fails its checksum: nothing of it was read" in error


def test_a_message_stamped_outside_its_chunks_span_is_a_corrupt_record(tmp_path: Path) -> None:
    """A log time no writer gave (it lies outside the span the index gives the chunk) would
    stop the clock for every formula: it ends the chunk's good prefix like any corrupt record."""
    good = bytearray(records(rows(0, 5)))
    good[2 * RECORD + 15 : 2 * RECORD + 23] = struct.pack("<Q", 2**63)
    path = tmp_path / "r.mcap"
    craft(path, [Chunk(rows(0, 5), data=bytes(good), crc=0), Chunk(rows(5, 2))])
    values, error = read(path)
    assert values == [0.0, 1.0, 5.0, 6.0]
    assert error is not None and "holds a message stamped 9223372036.854775808 s, outside" in error


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.data())
def test_any_chunk_header_gives_its_messages_or_a_prefix_of_them_and_one_line(
    tmp_path: Path, data: st.DataObject
) -> None:
    """Declared sizes up to 2**64, CRCs wrong or absent, compressions misnamed or unknown,
    compressed bytes cut short: the chunks beside it are read whole, it gives a prefix of its
    messages (never another value), and a header that lies ends in one line naming it (one
    that declares no bytes and holds none is an empty chunk)."""
    middle = data.draw(chunk_headers(rows(10, 5)))
    path = tmp_path / "r.mcap"
    at = craft(path, [Chunk(rows(0, 5)), middle, Chunk(rows(20, 5))])[1]
    values, error = read(path)
    assert values[:5] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert values[-5:] == [20.0, 21.0, 22.0, 23.0, 24.0]
    assert values[5:-5] == [10.0, 11.0, 12.0, 13.0, 14.0][: len(values) - 10]
    kept = readable_rows(middle)
    if kept is not None:
        assert error is None and values[5:-5] == [v for _, v in kept]
    else:
        assert error is not None and "\n" not in error and f"chunk at byte {at:,}" in error


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.integers(0, 10**6), st.binary(min_size=1, max_size=8))
def test_one_overwrite_inside_a_chunk_loses_at_most_the_rest_of_that_chunk(
    tmp_path: Path, at: int, junk: bytes
) -> None:
    """Bytes overwritten anywhere in a chunk with its CRC (its header or its records): the
    other chunks whole, a prefix of its own messages, one line when anything was lost."""
    path = tmp_path / "r.mcap"
    offsets = craft(path, [Chunk(rows(0, 5)), Chunk(rows(10, 5)), Chunk(rows(20, 5))])
    data = bytearray(path.read_bytes())
    at = offsets[1] + at % (offsets[2] - offsets[1])
    junk = junk[: offsets[2] - at]  # within the chunk
    data[at : at + len(junk)] = junk
    path.write_bytes(bytes(data))
    values, error = read(path)
    assert values[:5] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert values[-5:] == [20.0, 21.0, 22.0, 23.0, 24.0]
    assert values[5:-5] == [10.0, 11.0, 12.0, 13.0, 14.0][: len(values) - 10]
    assert (error is None and len(values) == 15) or (
        error is not None and "\n" not in error and f"chunk at byte {offsets[1]:,}" in error
    )
