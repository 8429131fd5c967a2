"""Damaged recordings are read up to the damage, in every format: the traffic example cut at
ten offsets still reports car2's violation whenever the cut leaves 300 s of data, and always
ends in one error line (exit 2) naming the file and what was lost.  Damage inside a chunk
loses only the rest of that chunk (the traffic recording is one chunk: a corrupt record at 6%
keeps the verdicts the records before it decide), `info` names it, and a file that is no
recording at all is refused from its first bytes."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import struct
from collections.abc import Iterable
from fractions import Fraction
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.monitor import Event, Monitor
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.recording import write_recording
from dkreason.stream.sources import JsonlSource, open_source
from dkreason.stream.units import NS, seconds_text

from .craft import Chunk, chunk_headers, read, readable_rows, records, rows
from .craft import write as craft

REPO = Path(__file__).resolve().parents[1]
TRAFFIC = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"
FORMATS = {
    "mcap": "rec",
    "bare-mcap": "rec.mcap",
    "sqlite3": "rec",
    "ros1": "rec.bag",
    "jsonl": "rec.jsonl",
}
CUTS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.93, 0.97)  # of the data file's bytes


def _simulate() -> ModuleType:  # examples/traffic/simulate.py, the traffic example's own recorder
    spec = importlib.util.spec_from_file_location("simulate", REPO / "examples/traffic/simulate.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _jsonl(path: Path, rows: Iterable[tuple[str, str, int, dict[str, Any]]]) -> None:
    with path.open("w") as out:
        for topic, _, t_ns, msg in rows:
            name = topic.removeprefix("/platform1/").lstrip("/")
            valid = msg.get("header", {}).get("stamp")
            body = {k: v for k, v in msg.items() if k != "header"}
            time = f"{t_ns // 10**9}.{t_ns % 10**9:09d}"
            stamp = f', "header": {{"stamp": {valid}}}' if valid is not None else ""
            out.write(
                f'{{"topic": "{name}", "time": {time}, "msg": {json.dumps(body)[:-1]}{stamp}}}}}\n'
            )


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    sim = _simulate()
    base = tmp_path_factory.mktemp("formats")
    out = {}
    for fmt, name in FORMATS.items():
        path = base / fmt / name
        path.parent.mkdir()
        if fmt == "jsonl":
            _jsonl(path, sim.messages())
        else:
            write_recording(path, fmt, sim.TYPES, sim.messages())  # type: ignore[arg-type]
        out[fmt] = path
    return out


@pytest.fixture(scope="module")
def km() -> KnowledgeManager:
    return KnowledgeManager.from_config(REPO / "examples" / "federation.toml")


def data_file(path: Path) -> Path:
    """The file holding the messages (a bag folder's storage file)."""
    return (
        next(p for p in path.iterdir() if p.suffix in (".mcap", ".db3")) if path.is_dir() else path
    )


def monitor(km: KnowledgeManager, path: Path) -> tuple[list[Event], DkError | None]:
    events: list[Event] = []
    error = None
    try:
        policy = StreamPolicy(delay_before_approximation=Fraction(1, 10))
        events.extend(Monitor(km.plan([TRAFFIC]), km.request, policy).run(open_source(path)))
    except DkError as exc:  # DamagedRecording, or a torn JSON line (file:line: not JSON)
        error = exc
    return events, error


def last_time(path: Path) -> int:
    """The record time of the last message before the damage (ns)."""
    source, last = open_source(path), 0
    try:
        rows = (
            source.records()
            if isinstance(source, JsonlSource)
            else source.messages({t: [] for t in source.types()})
        )
        for _, available, _, _ in rows:
            last = max(last, available)
    except DkError:
        pass
    return last


def violated(events: list[Event]) -> bool:
    return any(getattr(e, "verdict", None) is False and e.time == 300.02 for e in events)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_cut_recording_reports_what_the_data_before_the_cut_decides(
    tmp_path: Path, km: KnowledgeManager, recordings: dict[str, Path], fmt: str
) -> None:
    intact, _ = monitor(km, recordings[fmt])
    assert violated(intact)
    sides = set()
    for cut in CUTS:
        copy = tmp_path / f"{cut}" / recordings[fmt].name
        copy.parent.mkdir()
        if recordings[fmt].is_dir():
            shutil.copytree(recordings[fmt], copy)
        else:
            shutil.copy(recordings[fmt], copy)
        target = data_file(copy)
        data = target.read_bytes()
        kept = data[: int(len(data) * cut)]
        target.write_bytes(kept)
        events, error = monitor(km, copy)
        if fmt == "jsonl" and kept.endswith(b"\n"):  # cut between lines: nothing to notice
            assert error is None
        else:
            assert error is not None and str(copy.name) in str(error), (cut, error)
            assert "monitored" in str(error) or "not JSON" in str(error), (cut, error)
        covered = last_time(copy) >= 300_020_000_000  # the state that decides it
        assert violated(events) == covered, (fmt, cut, events)
        sides.add(covered)
    assert sides == {True, False}  # cuts on both sides of the deciding message


@pytest.mark.parametrize("fmt", ["mcap", "sqlite3"])
def test_a_bag_folder_without_metadata_is_read(
    tmp_path: Path, km: KnowledgeManager, recordings: dict[str, Path], fmt: str
) -> None:
    copy = tmp_path / "rec"
    shutil.copytree(recordings[fmt], copy)
    (copy / "metadata.yaml").unlink()
    events, error = monitor(km, copy)
    assert error is None and violated(events)
    (copy / "metadata.yaml").write_text("rosbag2_bagfile_information: [broken\n")
    events, error = monitor(km, copy)
    assert error is None and violated(events)


def test_the_cli_prints_the_verdict_then_one_error_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, recordings: dict[str, Path]
) -> None:
    cut = tmp_path / "cut.bag"
    data = recordings["ros1"].read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.95)])
    code = main(
        [
            "monitor",
            "--config",
            str(REPO / "examples" / "federation.toml"),
            "--source",
            str(cut),
            "--delay",
            "0.1",
            "--json",
            TRAFFIC,
        ]
    )
    out = capsys.readouterr()
    verdicts = [json.loads(line) for line in out.out.splitlines()]
    assert code == 2 and verdicts[0]["verdict"] is False and verdicts[0]["time"] == 300.02
    errors = [line for line in out.err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "cut.bag: damaged recording" in errors[0]


def _corrupt_record_at(recording: Path, share: float) -> int:
    """The length of the first record at or after `share` of the recording's one chunk (no
    CRC: rosbags writes none) made to run past the chunk; the record time before it (ns)."""
    from mcap.reader import make_reader

    path = data_file(recording)
    data = bytearray(path.read_bytes())
    with path.open("rb") as handle:
        (chunk,) = make_reader(handle).get_summary().chunk_indexes  # type: ignore[union-attr]
    pos = chunk.chunk_start_offset + 9 + 8 + 8 + 8 + 4 + 4 + 8  # its records, uncompressed
    last = 0
    while pos < len(data) * share:
        if data[pos] == 0x05:
            (last,) = struct.unpack_from("<Q", data, pos + 15)
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    data[pos + 1 : pos + 9] = struct.pack("<Q", 10**9)
    path.write_bytes(bytes(data))
    return int(last)


EARLY = [
    "always (Speed[car3] < 60)",
    "eventually (Position[car2] > 50)",
    "always (Speed[car1] < 90)",
]


def test_a_corrupt_record_at_6_percent_of_the_traffic_recording_keeps_what_came_before(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, traffic: Path
) -> None:
    """The traffic recording is one chunk: the verdicts decided before the damage are the
    intact run's, nothing is settled at the end from what was lost, and one line names it."""

    def run(recording: Path) -> tuple[int, list[dict[str, Any]], list[str]]:
        config = str(REPO / "examples" / "federation.toml")
        argv = ["monitor", "--config", config, "--source", str(recording), "--json", *EARLY]
        code = main([*argv[:5], "--delay", "0.1", *argv[5:]])
        out = capsys.readouterr()
        errors = [line for line in out.err.splitlines() if line.startswith("error: ")]
        return code, [json.loads(line) for line in out.out.splitlines()], errors

    damaged = tmp_path / "recording"
    shutil.copytree(traffic, damaged)
    until = _corrupt_record_at(damaged, 0.06)
    code, intact, _ = run(traffic)
    assert code == 1 and len(intact) == 3
    code, verdicts, errors = run(damaged)
    assert 20 * NS < until < 30 * NS
    assert code == 2 and verdicts == [v for v in intact if v["time"] * NS < until]
    assert len(verdicts) == 2
    assert (
        len(errors) == 1
        and "damaged recording: 1 of its 1 chunks damaged: the chunk at" in (errors[0])
    )
    assert re.search(
        r"holds a record running past its end: read up to 2\d\.\d+ s, the rest", errors[0]
    )
    assert main(["info", str(damaged)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert (
        out[0] == f"{damaged}: 8 topic(s), {seconds_text(until)} s from 0; header stamps: on the "
        "record clock"
    )
    assert out[-1].startswith("  damaged: the chunk at byte 43 (0 to 359.07 s) holds a record ")


def test_without_a_summary_damage_in_a_chunk_keeps_the_records_before_it(tmp_path: Path) -> None:
    """Read front to back (no index to find later chunks by), a chunk's records are read up to
    its damage, and the reading ends there in one line."""
    good, size = records(rows(10, 10)), len(records(rows(0, 1)))
    bad = good[: 4 * size] + b"\x05" + struct.pack("<Q", 10**6) + good[4 * size + 9 :]
    path = tmp_path / "r.mcap"
    craft(path, [Chunk(rows(0, 10)), Chunk(rows(10, 10), crc=0, data=bad)], summary=False)
    values, error = read(path)
    assert values == [float(t) for t in range(14)]
    assert error is not None and "\n" not in error
    assert "damaged recording" in error and "14 messages before it were monitored" in error


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.data())
def test_read_front_to_back_any_chunk_header_gives_a_prefix_and_one_line(
    tmp_path: Path, data: st.DataObject
) -> None:
    """Without a summary, a chunk whose header lies (its size, CRC, compression, bytes) ends
    the reading: the chunk before it whole, a prefix of its own messages, one line."""
    middle = data.draw(chunk_headers(rows(10, 5)))
    path = tmp_path / "r.mcap"
    craft(path, [Chunk(rows(0, 5)), middle, Chunk(rows(20, 5))], summary=False)
    values, error = read(path)
    assert values[:5] == [0.0, 1.0, 2.0, 3.0, 4.0]
    kept = readable_rows(middle)
    if kept is not None:
        assert error is None and values[5:] == [v for _, v in kept] + [*map(float, range(20, 25))]
    else:
        assert values[5:] == [10.0, 11.0, 12.0, 13.0, 14.0][: len(values) - 5]
        assert error is not None and "\n" not in error


def test_an_empty_chunk_whose_header_says_so_is_read_past(tmp_path: Path) -> None:
    """A chunk of no bytes, declaring none and no CRC, is a valid empty chunk: nothing in the
    file says records were lost, so the reading goes on (a case hypothesis found)."""
    middle = Chunk(rows(10, 5), "", 0, 0, b"")
    path = tmp_path / "r.mcap"
    craft(path, [Chunk(rows(0, 5)), middle, Chunk(rows(20, 5))], summary=False)
    assert readable_rows(middle) == ()
    assert read(path) == ([*map(float, range(5)), *map(float, range(20, 25))], None)


def test_a_bomb_in_a_file_without_a_summary_is_refused_unread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rosbags scans such a file, inflating every chunk: its decompressors are bounded too,
    and the sequential reader then reads up to the bomb."""
    import zstandard

    from .craft import zstd_bomb

    path = tmp_path / "bomb.mcap"
    craft(
        path, [Chunk(rows(0, 3)), Chunk(rows(3, 3), "zstd", 2**31, 0, zstd_bomb())], summary=False
    )
    monkeypatch.setattr(zstandard, "ZstdDecompressor", None)  # any use fails the test
    values, error = read(path)
    assert values == [0.0, 1.0, 2.0]
    assert error is not None and "a chunk declares 2,147,483,648 bytes, more than 1,000 times" in (
        error
    )


def test_a_gigabyte_of_zeros_named_bag_is_refused_from_its_first_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """rosbags reads a .bag's first line whole (3.2 GB for 1 GiB of zeros): a file that does
    not begin as a recording of its kind is refused before any reader sees it."""
    import rosbags.highlevel

    zeros = tmp_path / "zeros.bag"
    with zeros.open("wb") as out:
        out.truncate(2**30)  # sparse: no disk used
    monkeypatch.setattr(rosbags.highlevel, "AnyReader", None)  # any use fails the test
    code = main(["info", str(zeros)])
    err = capsys.readouterr().err
    assert code == 2 and err == (
        f"error: {zeros}: not a readable ROS recording (it does not begin as a ROS 1 bag "
        f"(format 2.0) does)\n"
    )
    os.truncate(zeros, 0)


@pytest.mark.parametrize(
    ("name", "magic", "says"),
    [
        ("z.bag", b"#ROSBAG V2.0\n", "a record without its op field (byte 21 of 1,073,741,824)"),
        (
            "z.mcap",
            b"\x89MCAP0\r\n",
            "a record of no kind (opcode 0x00) (byte 17 of 1,073,741,824)",
        ),
    ],
)
def test_zeros_after_a_recordings_first_bytes_end_the_reading_at_the_first_record(
    tmp_path: Path, name: str, magic: bytes, says: str
) -> None:
    """Read record by record, zeros are records of nothing, 9 bytes each: the first ends it."""
    path = tmp_path / name
    path.write_bytes(magic)
    os.truncate(path, 2**30)  # sparse
    values, error = read(path)
    assert values == [] and error == f"{path}: not a readable ROS recording ({says})"
    os.truncate(path, 0)


def test_info_on_a_recording_whose_only_chunk_is_unreadable_names_it_and_no_span(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Not the index's counts as if the file were intact, nor rosbags' empty span (2**63 ns
    from 0): what was read, and the damage."""
    from .craft import zstd_bomb

    path = tmp_path / "r.mcap"
    craft(path, [Chunk(rows(3, 3), "zstd", 2**31, 0, zstd_bomb())])
    assert main(["info", str(path)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"{path}: 1 topic(s); header stamps: none",
        "  /a  std_msgs/msg/Float64  0",
        "  damaged: the chunk at byte 126 (3 to 5 s) declares 2,147,483,648 bytes, more than "
        "1,000 times its 65,558 compressed bytes (raise DKREASON_MAX_CHUNK_RATIO to read it): "
        "nothing of it was read",
    ]
