"""The indexed MCAP reader gives what rosbags gives, in rosbags' order, on any chunking.

Real recordings are chunked and compressed in different ways (zstd by `ros2 bag record`'s
presets, lz4, none), messages may be written out of time order within a chunk (several
publishers, one writer) and chunks may overlap in time.  The reader's order is checked
against rosbags' own on files written that way (hypothesis), and a damaged chunk stops the
replay with a one-line error after the messages before it.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason.errors import DkError
from dkreason.stream.damaged import DamagedRecording
from dkreason.stream.mcapread import open_indexed
from dkreason.stream.sources import RosbagSource

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


def test_a_corrupt_chunk_stops_after_the_messages_before_it(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    write(path, [(0, t, float(t)) for t in range(200)], chunk_size=500, compression="")
    data = bytearray(path.read_bytes())
    at = data.index(struct.pack("<d", 150.0))
    data[at : at + 8] = b"\xff" * 8  # a chunk's bytes no longer match its CRC
    path.write_bytes(bytes(data))
    seen: list[float] = []
    source = RosbagSource(path)
    with pytest.raises(DamagedRecording, match="checksum") as err:
        for _, _, _, (v,) in source.messages({"/a": ["msg.data"]}):
            seen.append(v)
    source.close()
    assert seen == [float(t) for t in range(len(seen))] and 0 < len(seen) < 150
    assert "\n" not in str(err.value) and f"{len(seen)} messages" in str(err.value)


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
