"""Verdicts where robotics engineers look: `monitor --record` over recordings of every kind
(the relevant topics byte for byte, the events as Foxglove's `foxglove.Log` and as JSON),
`--clips` (one small MCAP per violation), and `--foxglove` (served live)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.progress import Verdict
from dkreason.stream.recording import write_recording

from .test_monitor import SLOW, SPEEDING, TYPES, car_rows

REPO = Path(__file__).resolve().parents[1]
SINGLE = REPO / "examples" / "single.toml"
LOG_SCHEMA = json.loads((Path(__file__).parent / "data" / "foxglove" / "Log.json").read_text())
S = 10**9


def read_mcap(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, schema name, log time, data) of every message, with the mcap reader."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return [
            (channel.topic, schema.name if schema else "", message.log_time, message.data)
            for schema, channel, message in make_reader(f).iter_messages()
        ]


def recorded(path: Path) -> list[tuple[str, int, bytes]]:
    """The messages of a recording as rosbags reads them: (topic, record time, CDR bytes: a
    ROS 1 message converted)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        return [
            (c.topic, t, bytes(raw if reader.is2 else reader.typestore.ros1_to_cdr(raw, c.msgtype)))
            for c, t, raw in reader.messages()
        ]


def verdicts(capsys: pytest.CaptureFixture[str], source: Path, *extra: str) -> list[Any]:
    code = main(
        ["monitor", "--config", str(SINGLE), "--source", str(source), "--json", *extra]
        + [SPEEDING, SLOW]
    )
    assert code == 1
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


@pytest.mark.parametrize("fmt", ["ros1", "sqlite3", "bare-mcap"])
def test_record_offline_keeps_the_topics_and_logs_the_verdicts_for_foxglove(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, fmt: str
) -> None:
    source = tmp_path / {"ros1": "run.bag", "bare-mcap": "run.mcap"}.get(fmt, "run")
    write_recording(source, fmt, TYPES, car_rows())  # type: ignore[arg-type]
    out = tmp_path / "out.mcap"
    said = verdicts(capsys, source, "--record", str(out))
    messages = read_mcap(out)
    # the relevant topics byte for byte (ROS 1: as CDR), at their record times
    copied = [(t, at, data) for t, _, at, data in messages if t.startswith("/platform1/")]
    assert copied == recorded(source) and len(copied) == 16
    logs = [json.loads(data) for t, _, _, data in messages if t == "/dkreason/log"]
    for line in logs:
        jsonschema.validate(line, LOG_SCHEMA)
    assert {name for t, name, _, _ in messages if t == "/dkreason/log"} == {"foxglove.Log"}
    violated = next(e for e in said if e.get("verdict") is False)
    assert [(g["name"], g["level"], g["message"], g["timestamp"]) for g in logs] == [
        ("dkreason", 2, f"monitoring {source}", {"sec": 0, "nsec": 0}),
        (SPEEDING, 4, violated["witness"], {"sec": 3, "nsec": 100_000_000}),
        (SLOW, 2, "held at t+7 s", {"sec": 7, "nsec": 0}),
    ]
    events = [json.loads(data) for t, _, _, data in messages if t == "/dkreason/events"]
    assert events == said
    # replayed, the record gives the same verdicts
    assert verdicts(capsys, out) == said


def test_clips_hold_the_messages_around_each_witness_window(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", TYPES, car_rows())
    clips = tmp_path / "clips"
    clips.mkdir()
    code = main(
        ["monitor", "--config", str(SINGLE), "--source", str(source), "--clips", str(clips)]
        + ["--clip-margin", "0.5", "--record", str(tmp_path / "all.mcap"), SPEEDING, SLOW]
    )
    assert code == 1
    assert f"clip {clips / 'violation-1.mcap'}: {SPEEDING}" in capsys.readouterr().out
    assert sorted(p.name for p in clips.iterdir()) == ["violation-1.mcap"]
    clip = read_mcap(clips / "violation-1.mcap")
    # the witness window is [0.1, 3.1] (car1 speeding from 0.1 s, never slow within 3 s)
    lo, hi = S // 10 - S // 2, 3 * S + S // 10 + S // 2
    whole = read_mcap(tmp_path / "all.mcap")
    want = [m for m in whole if m[0].startswith("/platform1/") and lo <= m[2] <= hi]
    assert [m for m in clip if m[0].startswith("/platform1/")] == want and len(want) == 8
    (log,) = [json.loads(m[3]) for m in clip if m[0] == "/dkreason/log"]
    assert (log["name"], log["level"]) == (SPEEDING, 4)


def test_the_facade_records_as_the_cli_does(tmp_path: Path) -> None:
    source = tmp_path / "run.bag"
    write_recording(source, "ros1", TYPES, car_rows())
    km = KnowledgeManager.from_config(SINGLE)
    run = km.monitor([SPEEDING], [source], record=tmp_path / "out.mcap", clips=tmp_path)
    events = list(run)
    (verdict,) = [e for e in events if isinstance(e, Verdict)]
    assert verdict.window == (0.1, 3.1)
    assert [(p.name, v) for p, v in run.written] == [("violation-1.mcap", verdict)]  # type: ignore[attr-defined]
    again = list(km.monitor([SPEEDING], [tmp_path / "out.mcap"]))
    assert again == events


def test_record_is_refused_for_live_federation_and_clips_for_live(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    base = ["monitor", "--config", str(SINGLE), SPEEDING]
    assert main([*base, "--live", "--record", str(tmp_path / "x.mcap")]) == 2
    assert "--record is for recordings and --ros2" in capsys.readouterr().err
    assert main([*base, "--ros2", "--clips", str(tmp_path)]) == 2
    assert "--clips is for recordings" in capsys.readouterr().err
