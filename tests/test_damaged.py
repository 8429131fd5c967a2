"""Damaged recordings are read up to the damage, in every format: the traffic example cut at
ten offsets still reports car2's violation whenever the cut leaves 300 s of data, and always
ends in one error line (exit 2) naming the file and what was lost."""

from __future__ import annotations

import importlib.util
import json
import shutil
from collections.abc import Iterable
from fractions import Fraction
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.monitor import Event, Monitor
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.recording import write_recording
from dkreason.stream.sources import JsonlSource, open_source

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
