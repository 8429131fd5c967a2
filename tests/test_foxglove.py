"""Verdicts where robotics engineers look: `monitor --record` over recordings of every kind
(the relevant topics byte for byte, the events as Foxglove's `foxglove.Log` and as JSON),
`--clips` (one small MCAP per violation), and `--foxglove` (served live)."""

from __future__ import annotations

import json
import socket
import struct
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.live.viewer import Viewer
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


def test_a_recorded_verdict_says_its_robustness_in_the_log(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """With --robustness, Foxglove's Log panel shows by how much, and from where, below the
    witness."""
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", TYPES, car_rows())
    out = tmp_path / "out.mcap"
    said = verdicts(capsys, source, "--robustness", "--record", str(out))
    violated = next(e for e in said if e.get("verdict") is False)
    logs = [json.loads(d) for t, _, _, d in read_mcap(out) if t == "/dkreason/log"]
    (line,) = [g for g in logs if g["name"] == SPEEDING]
    assert line["message"].startswith(violated["witness"] + "\nrobustness: violated by 10 ")


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


# ---- --foxglove: the run served over Foxglove's WebSocket protocol ---------------------


class Watching:
    """A WebSocket client doing what Foxglove does on connecting: it reads the server's
    advertised channels, subscribes to them all, and reads message data (each subscription
    numbered as its channel)."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        assert json.loads(self.ws.recv())["op"] == "serverInfo"
        advertised = json.loads(self.ws.recv())
        assert advertised["op"] == "advertise"
        self.channels = {c["id"]: c for c in advertised["channels"]}
        self.got: list[tuple[str, int, Any]] = []  # (topic, log time, message)

    def subscribe(self, *topics: str) -> None:
        """To `topics` (all channels if none are named)."""
        subscriptions = [
            {"id": n, "channelId": n}
            for n, c in self.channels.items()
            if not topics or c["topic"] in topics
        ]
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def read_until(self, done: Any) -> None:
        """Messages read until `done(self.got)` (a channel advertised late is subscribed to);
        the timeout only stops a test that would hang."""
        while not done(self.got):
            frame = self.ws.recv(timeout=30)
            if isinstance(frame, str):
                more = json.loads(frame)
                if more["op"] == "advertise":
                    self.channels.update({c["id"]: c for c in more["channels"]})
                    self.subscribe()
                continue
            opcode, sub, at = struct.unpack_from("<BIQ", frame)
            assert opcode == 1  # message data
            self.got.append((self.channels[sub]["topic"], at, json.loads(frame[13:])))


@contextmanager
def watching(url: str) -> Iterator[Watching]:
    from websockets.sync.client import connect
    from websockets.typing import Subprotocol

    with connect(url, subprotocols=[Subprotocol("foxglove.sdk.v1")]) as ws:
        yield Watching(ws)


def test_foxglove_serves_features_and_verdicts_as_the_run_goes(tmp_path: Path) -> None:
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", TYPES, car_rows())
    km = KnowledgeManager.from_config(SINGLE)
    with km.monitor([SPEEDING, SLOW], [source], foxglove="127.0.0.1:0", speed=0) as run:
        assert run.watcher is not None
        with watching(run.watcher.url) as client:
            advertised = {c["topic"]: c for c in client.channels.values()}
            assert set(advertised) == {
                "/dkreason/feature/Speed/car1",
                "/dkreason/feature/Speed/car2",
                "/dkreason/log",
                "/dkreason/events",
            }
            assert advertised["/dkreason/log"]["schemaName"] == "foxglove.Log"
            assert {c["encoding"] for c in advertised.values()} == {"json"}
            client.subscribe()
            assert isinstance(run.watcher, Viewer)  # every channel subscribed, not only the first:
            assert run.watcher.subscribed(len(advertised), timeout=60)
            events = list(run)  # the replay starts once the client subscribed
            said = [e.to_json() for e in events]
            client.read_until(lambda got: len([g for g in got if g[0] == "/dkreason/events"]) == 2)
    by_topic: dict[str, list[tuple[int, Any]]] = {}
    for topic, at, message in client.got:
        by_topic.setdefault(topic, []).append((at, message))
    # each sample's value at its state's time: car1 at 0.1 s, 1.1 s, …; car2 at 0 s, 1 s, …
    car1 = by_topic["/dkreason/feature/Speed/car1"]
    assert car1[:2] == [(S // 10, {"value": 70.0}), (S + S // 10, {"value": 70.0})]
    assert len(car1) == 8 and len(by_topic["/dkreason/feature/Speed/car2"]) == 8
    logs = by_topic["/dkreason/log"]
    for _, line in logs:
        jsonschema.validate(line, LOG_SCHEMA)
    violated = next(e for e in said if e.get("verdict") is False)
    assert [(at, g["name"], g["level"], g["message"]) for at, g in logs] == [
        (3 * S + S // 10, SPEEDING, 4, violated["witness"]),
        (7 * S, SLOW, 2, "held at t+7 s"),
    ]
    assert [e for _, e in by_topic["/dkreason/events"]] == said


def test_monitor_foxglove_on_the_command_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dkreason.live import viewer

    source = tmp_path / "run.bag"
    write_recording(source, "ros1", TYPES, car_rows())
    started: list[viewer.Viewer] = []
    serving = threading.Event()

    class Seen(viewer.Viewer):  # the CLI's viewer, made known to the test
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            started.append(self)
            serving.set()

    monkeypatch.setattr(viewer, "Viewer", Seen)
    codes: list[int] = []
    cli = threading.Thread(
        target=lambda: codes.append(
            main(
                ["monitor", "--config", str(SINGLE), "--source", str(source), "--json"]
                + ["--foxglove", "127.0.0.1:0", "--speed", "0", SPEEDING]
            )
        )
    )
    cli.start()
    assert serving.wait(30)
    url = started[0].url
    with watching(url) as client:  # the log alone: the replay starts at the first subscription
        client.subscribe("/dkreason/log")
        client.read_until(lambda got: any(topic == "/dkreason/log" for topic, _, _ in got))
    cli.join()
    assert codes == [1]
    assert f"serving Foxglove on {url}: the replay starts" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("given", "error"),
    [
        ("99999", "--foxglove '99999': expected [HOST:]PORT"),
        ("robot:", "--foxglove 'robot:': expected [HOST:]PORT"),
        ("taken", "Address already in use"),
    ],
)
def test_foxglove_port_taken_or_malformed_is_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, given: str, error: str
) -> None:
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", TYPES, car_rows(2))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        if given == "taken":
            given = f"127.0.0.1:{taken.getsockname()[1]}"
        code = main(
            ["monitor", "--config", str(SINGLE), "--source", str(source)]
            + ["--foxglove", given, SPEEDING]
        )
    err = capsys.readouterr().err
    assert code == 2 and error in err and len(err.splitlines()) == 1


def test_speed_is_for_recordings(capsys: pytest.CaptureFixture[str]) -> None:
    base = ["monitor", "--config", str(SINGLE), SPEEDING]
    assert main([*base, "--live", "--speed", "2"]) == 2
    assert "--speed is for recordings" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        main([*base, "--speed", "-1"])
    assert stop.value.code == 2
    assert "expected 0 or more" in capsys.readouterr().err


def test_record_refuses_an_existing_file_before_the_run_unless_forced(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Issue 27, defect 7: `--record` overwrote an existing file without a word."""
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", TYPES, car_rows())
    kept = tmp_path / "yesterday.mcap"
    kept.write_bytes(b"a run worth keeping")
    argv = ["monitor", "--config", str(SINGLE), "--source", str(source), "--record", str(kept)]
    assert main([*argv, SPEEDING]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the file exists (give --force to overwrite it)" in err
    assert kept.read_bytes() == b"a run worth keeping"
    assert main([*argv, "--force", SPEEDING]) == 1  # overwritten, as asked
    assert read_mcap(kept)
