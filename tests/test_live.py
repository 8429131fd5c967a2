"""A live federation over Zenoh (issue 8): platform nodes and a monitor in separate processes on
loopback (explicit endpoints, no multicast), and the knowledge base changes they cause."""

from __future__ import annotations

import json
import queue
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.kb import KnowledgeBase
from dkreason.live.inbox import Inbox

from .conftest import REPO
from .test_federation import map_car3_to_a_truck

SPEEDING = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"
POSITION = "always (Position[car2] >= 0)"
ALTITUDE = "forall x in UAV: always (Altitude[x] > 10)"
CLI = [sys.executable, "-m", "dkreason.cli"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def site(tmp_path: Path) -> Path:
    """A copy of the bundled platforms, so specs added while running stay in the test."""
    for part in ("ontologies", "specs"):
        shutil.copytree(REPO / part, tmp_path / part)
    shutil.copytree(REPO / "examples" / "live", tmp_path / "examples" / "live")
    return tmp_path / "examples" / "live"


class Processes:
    """Every process a test starts, stopped however the test ends."""

    def __init__(self) -> None:
        self.all: list[subprocess.Popen[str]] = []

    def start(self, *args: str, stdin: Any = None) -> subprocess.Popen[str]:
        proc = subprocess.Popen(
            [*CLI, *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=stdin,
            text=True,
            cwd=REPO,
        )
        self.all.append(proc)
        return proc

    def stop(self) -> None:
        for proc in self.all:
            if proc.poll() is None:
                proc.terminate()
        for proc in self.all:
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            for pipe in (proc.stdout, proc.stderr):
                if pipe is not None:
                    pipe.close()


@pytest.fixture
def procs() -> Iterator[Processes]:
    p = Processes()
    try:
        yield p
    finally:
        p.stop()


def lines_of(proc: subprocess.Popen[str]) -> queue.Queue[dict[str, Any] | None]:
    """The monitor's JSON lines as they come; None at its end."""
    out: queue.Queue[dict[str, Any] | None] = queue.Queue()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.strip():
                out.put(json.loads(line))
        out.put(None)

    threading.Thread(target=read, daemon=True).start()
    return out


def log_of(proc: subprocess.Popen[str]) -> list[str]:
    """The process's stderr lines as they come (read by a thread, so it never blocks)."""
    lines: list[str] = []

    def read() -> None:
        assert proc.stderr is not None
        lines.extend(proc.stderr)

    threading.Thread(target=read, daemon=True).start()
    return lines


def logged(lines: list[str], *needles: str, timeout: float = 30.0) -> None:
    """Wait until every needle has appeared in the log."""
    deadline = time.monotonic() + timeout
    while not all(any(n in line for line in list(lines)) for n in needles):
        assert time.monotonic() < deadline, f"never logged: {needles}"
        time.sleep(0.02)


def wait_for(
    events: queue.Queue[dict[str, Any] | None],
    seen: list[dict[str, Any]],
    timeout: float = 15.0,
    since: int = 0,
    **fields: Any,
) -> dict[str, Any]:
    """The first event from `seen[since]` on with these fields, reading more as needed."""
    deadline = time.monotonic() + timeout
    for event in seen[since:]:
        if fields.items() <= event.items():
            return event
    while True:
        got = events.get(timeout=max(0.01, deadline - time.monotonic()))
        assert got is not None, f"the monitor ended before {fields}"
        seen.append(got)
        if fields.items() <= got.items():
            return got


def untimed(verdict: dict[str, Any]) -> dict[str, Any]:
    """A verdict (and its instances) on the recording's clock only: without `t`, and its
    witnesses' `t+…` times as times on that clock.  `t` counts from the first message a
    monitor saw, and a live one and one of the recording may see different first messages."""
    timed = verdict.get("time") is not None and verdict.get("t") is not None
    origin = Decimal(str(verdict["time"])) - Decimal(str(verdict["t"])) if timed else Decimal(0)

    def clocked(said: dict[str, Any]) -> dict[str, Any]:
        out = {k: v for k, v in said.items() if k != "t"}
        if isinstance(out.get("witness"), str):
            out["witness"] = re.sub(
                r"t([+-][0-9.]+)",
                lambda m: format((Decimal(m.group(1)) + origin).normalize(), "f"),
                out["witness"],
            )
        return out

    out = clocked(verdict)
    if "instances" in out:
        out["instances"] = [clocked(i) for i in out["instances"]]
    return out


@contextmanager
def platform1_live(
    scenario: Path, formulas: list[str], policy: Any = None
) -> Iterator[tuple[Any, Any, list[Any]]]:
    """Platform 1 of the scenario as a node and a live monitor of `formulas` on platform 1's
    vocabulary, over loopback Zenoh (node, monitor, [the monitor's, the node's session]);
    closed on leaving.  `policy`: the monitor's (default: StreamPolicy())."""
    from dkreason.live.monitor import LiveMonitor
    from dkreason.live.serve import PlatformNode
    from dkreason.live.session import open_session
    from dkreason.stream.policy import StreamPolicy

    (scenario / "monitor.toml").write_text('local = "platform1"\n[platforms.platform1]\n')
    (scenario / "p1.toml").write_text(
        '[platforms.platform1]\nontology = "ontologies/platform1.owl"\n'
        'specs = "specs/platform1.sslt"\n'
    )
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    sessions = [open_session([], [endpoint]), open_session([endpoint], [])]
    node = PlatformNode(KnowledgeManager.from_config(scenario / "p1.toml"), sessions[1])
    monitor = LiveMonitor(
        KnowledgeManager.from_config(scenario / "monitor.toml", live=True),
        formulas,
        policy or StreamPolicy(),
        sessions[0],
        wait=10,
    )
    try:
        yield node, monitor, sessions
    finally:
        node.close()
        for session in sessions:
            session.close()


def heard(publisher: Any, timeout: float = 30.0) -> Any:
    """The publisher, once a subscriber on its key is known to its session (an event, not a
    sleep: on a loaded machine a declaration may take seconds to arrive)."""
    deadline = time.monotonic() + timeout
    while not publisher.matching_status.matching:
        assert time.monotonic() < deadline, f"nobody subscribed to {publisher.key_expr}"
        time.sleep(0.02)
    return publisher


def subscription_known(port: int, key: str) -> None:
    """Wait until a fresh session on the monitor's endpoint sees its subscription to `key`:
    the declaration has then reached the peers connected there."""
    from dkreason.live.session import open_session

    probe = open_session([f"tcp/127.0.0.1:{port}"], [])
    try:
        heard(probe.declare_publisher(key)).undeclare()
    finally:
        probe.close()


def serve(
    procs: Processes, site: Path, n: int, port: int, recording: Path, origin: float, speed: float
) -> subprocess.Popen[str]:
    return procs.start(
        "serve",
        "--config",
        str(site / f"platform{n}.toml"),
        "--connect",
        f"tcp/127.0.0.1:{port}",
        "--source",
        str(recording),
        "--origin",
        str(origin),
        "--speed",
        str(speed),
    )


def federation(
    procs: Processes, site: Path, traffic: Path, speed: float, *monitor_args: str
) -> tuple[
    subprocess.Popen[str],
    queue.Queue[dict[str, Any] | None],
    list[dict[str, Any]],
    dict[int, subprocess.Popen[str]],
    float,
    int,
]:
    """A live monitor and the three platform nodes replaying the traffic example in step,
    started over with a larger margin until everything is in place before the replay starts
    (on a loaded machine the first samples could otherwise go out before anyone listens)."""
    for margin in (6.0, 20.0, 60.0):
        port = free_port()
        monitor = procs.start(
            "monitor",
            "--live",
            "--config",
            str(site / "monitor.toml"),
            "--listen",
            f"tcp/127.0.0.1:{port}",
            "--wait",
            "20",
            "--json",
            *monitor_args,
        )
        events, seen = lines_of(monitor), list[dict[str, Any]]()
        origin = time.time() + margin
        nodes = {n: serve(procs, site, n, port, traffic, origin, speed) for n in (1, 2, 3)}
        for n in (1, 2, 3):
            wait_for(events, seen, event="joined", platform=f"platform{n}", timeout=60)
        wait_for(
            events, seen, event="subscribed", platform="platform2", topic="carstopic3", timeout=60
        )
        subscription_known(port, "dkreason/platform2/topic/carstopic3")
        if time.time() < origin - 1:
            break
        procs.stop()
        procs.all.clear()
    return monitor, events, seen, nodes, origin, port


def test_live_federation_adapts_and_gives_the_recorded_verdict(
    procs: Processes, site: Path, traffic: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        main(
            [
                "monitor",
                "--config",
                str(REPO / "examples" / "federation.toml"),
                "--source",
                str(traffic),
                "--delay",
                "0.1",
                "--json",
                SPEEDING,
            ]
        )
        == 1
    )
    recorded = [json.loads(line) for line in capsys.readouterr().out.splitlines()]

    speed = 20.0
    monitor, events, seen, nodes, origin, port = federation(
        procs,
        site,
        traffic,
        speed,
        "--delay",
        "0.1",
        "--until",
        "330",
        SPEEDING,
        POSITION,
        ALTITUDE,
    )

    # platform 2 crashes at about 60 s of stream time: Position[car2] loses its only topic
    time.sleep(max(0.0, origin + 60 / speed - time.time()))
    nodes[2].kill()
    lost = wait_for(events, seen, event="source_lost", feature="Position[car2]")
    assert lost["platform"] == "platform2" and "went away" in lost["detail"]
    assert monitor.poll() is None

    # it comes back, and is used again
    nodes[2] = serve(procs, site, 2, port, traffic, origin, speed)
    back = len(seen)
    wait_for(events, seen, since=back, event="joined", platform="platform2", timeout=20)
    wait_for(events, seen, since=back, event="subscribed", platform="platform2", topic="carstopic3")

    # a topic specification added on platform 3 while running brings a new subscription
    added = subprocess.run(
        [
            *CLI,
            "specs",
            "add",
            "--config",
            str(site / "platform3.toml"),
            "topic uastopic9:UasMsg contains Height(uas21) = msg.height for uas21 = msg.id",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert added.returncode == 0, added.stderr
    wait_for(
        events,
        seen,
        event="subscribed",
        platform="platform3",
        topic="uastopic9",
        feature="Altitude[uav2]",
    )

    assert monitor.wait(timeout=40) == 1
    while (event := events.get(timeout=5)) is not None:
        seen.append(event)
    verdicts = {e["formula"]: e for e in seen if "verdict" in e and "update" not in e}
    assert untimed(verdicts[SPEEDING]) == untimed(recorded[0])  # verdict, time, witness and
    # instances are the same; `t` counts from the first sample each monitor saw
    assert verdicts[POSITION]["verdict"] is None  # no verdict on data that was not there
    # unknown from when its last sample grew older than the maximum age (5 s), not before
    gap = verdicts[POSITION]["unknown"][0]
    assert gap["feature"] == "Position[car2]" and not gap.get("silent")
    assert abs(gap["from"] - (lost["last_sample"] + 5)) < 1e-6
    assert lost["last_sample"] > 50  # it was fed until platform 2 went away at about 60 s
    assert monitor.stderr is not None
    assert "Traceback" not in monitor.stderr.read()


def test_live_gives_the_offline_verdicts_when_the_replays_end(
    procs: Processes, site: Path, traffic: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Three nodes replay the traffic example to its end; the monitor, given no --until,
    ends with them, and every verdict equals `monitor --source` on the same recording (a
    feature is not left to go stale on a clock that outlives the replay)."""
    assert (
        main(
            [
                "monitor",
                "--config",
                str(REPO / "examples" / "federation.toml"),
                "--source",
                str(traffic),
                "--json",
                SPEEDING,
                POSITION,
            ]
        )
        == 1
    )
    offline = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    monitor, events, seen, _, _, _ = federation(procs, site, traffic, 60.0, SPEEDING, POSITION)
    assert monitor.wait(timeout=120) == 1
    while (event := events.get(timeout=5)) is not None:
        seen.append(event)
    live = [e for e in seen if "verdict" in e]
    # `t` counts from the first sample each monitor saw; the verdicts themselves are equal
    assert [untimed(v) for v in live] == [untimed(v) for v in offline]


def test_monitor_trusts_only_its_platforms_and_survives_bad_payloads(
    procs: Processes, tmp_path: Path, traffic: Path
) -> None:
    import zenoh

    from dkreason.live.session import open_session

    (tmp_path / "monitor.toml").write_text(
        'local = "platform1"\n[platforms.platform1]\n[platforms.platform9]\n'
    )
    (tmp_path / "platform1.toml").write_text(
        f'[platforms.platform1]\nontology = "{REPO}/ontologies/platform1.owl"\n'
        f'specs = "{REPO}/specs/platform1.sslt"\n'
    )
    port = free_port()
    monitor = procs.start(
        "monitor",
        "--live",
        "--config",
        str(tmp_path / "monitor.toml"),
        "--listen",
        f"tcp/127.0.0.1:{port}",
        "--until",
        "200",
        "--wait",
        "20",
        "--json",
        "always (Speed[car1] < 100)",
    )
    events, seen = lines_of(monitor), list[dict[str, Any]]()
    rogue = open_session([f"tcp/127.0.0.1:{port}"], [])
    try:
        token = rogue.liveliness().declare_token("dkreason/intruder/alive")
        # a configured platform whose node answers with a broken ontology
        broken = rogue.declare_queryable(
            "dkreason/platform9/ontology",
            lambda q: q.reply(
                "dkreason/platform9/ontology", b'{"file": "p9.owl", "turtle": "@prefix broken"}'
            ),
        )
        token9 = rogue.liveliness().declare_token("dkreason/platform9/alive")
        origin = time.time() + 4
        procs.start(
            "serve",
            "--config",
            str(tmp_path / "platform1.toml"),
            "--connect",
            f"tcp/127.0.0.1:{port}",
            "--source",
            str(traffic),
            "--origin",
            str(origin),
            "--speed",
            "60",
        )
        wait_for(events, seen, event="subscribed", platform="platform1", topic="topic3")
        bad = heard(
            rogue.declare_publisher(
                "dkreason/platform1/topic/topic3", congestion_control=zenoh.CongestionControl.BLOCK
            )
        )
        for payload in (
            b"not json",
            b"[" * 100_000,
            b'{"valid": "soon", "msg": {}}',
            b'{"valid": 1, "msg": {"id": 1}}',
            bytes([0xFF, 0xFE]),
            b"[" * 30_000,
            b'{"valid": 1, "msg": {"id": 1, "spd": ' + b"9" * 5000 + b"}}",
            b'{"valid": 1, "msg": {"id": 1, "spd": "far"}}',
            b'{"valid": 1, "msg": {"id": [1], "spd": 3}}',
        ):
            bad.put(payload)
        rogue.put(
            "dkreason/intruder/topic/topic3",
            b'{"valid": 1, "msg": {"id": 1}}',
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        assert monitor.wait(timeout=30) == 0
        for entity in (token, token9, broken):
            entity.undeclare()
    finally:
        rogue.close()
    while (event := events.get(timeout=5)) is not None:
        seen.append(event)
    assert [e["verdict"] for e in seen if "verdict" in e] == [True]
    assert monitor.stderr is not None
    log = monitor.stderr.read()
    assert log.count("ignoring platform intruder") == 1
    assert "more than the 65536 allowed" in log and "not JSON" in log
    assert "has no field msg.spd" in log and "str 'far' is not a number or boolean" in log
    assert "rejected knowledge from platform9" in log and "p9.owl" in log
    assert "Traceback" not in log
    assert not any(e.get("platform") == "intruder" for e in seen)


def test_monitor_without_its_local_platform_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "monitor.toml").write_text('local = "platform1"\n[platforms.platform1]\n')
    code = main(
        [
            "monitor",
            "--live",
            "--config",
            str(tmp_path / "monitor.toml"),
            "--listen",
            f"tcp/127.0.0.1:{free_port()}",
            "--wait",
            "0.5",
            "always (Speed[car1] < 1)",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err[-1] == (
        "error: the local platform platform1 did not appear within 0.5 s (is "
        "`dkreason serve` running for it, on a reachable endpoint?)"
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["monitor", "--config", "examples/federation.toml", "always (Speed[car1] < 1)"],
            "error: monitor needs --source RECORDING, or --live",
        ),
        (
            ["serve", "--config", "examples/federation.toml", "--listen", "nonsense"],
            "error: zenoh: bad endpoint 'nonsense' (expected <protocol>/<address>",
        ),
        (
            ["serve", "--config", "examples/federation.toml", "--listen", "tcp/256.1.1.1:1"],
            "error: zenoh: cannot open a session",
        ),
        (
            [
                "monitor",
                "--live",
                "--config",
                "examples/live/monitor.toml",
                "--wait",
                "0.1",
                "always (Speed[car1] <",
            ],
            "error: <formula>:1:23: syntax error",
        ),
        (
            [
                "monitor",
                "--config",
                "examples/live/monitor.toml",
                "--source",
                "x.jsonl",
                "always (Speed[car1] < 1)",
            ],
            "error: examples/live/monitor.toml: [platforms.platform1] has no ontology file",
        ),
    ],
)
def test_bad_live_invocations_give_one_line(
    args: list[str],
    message: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(REPO)
    assert main(args) == 2
    out = capsys.readouterr()
    lines = [
        line for line in (out.out + out.err).splitlines() if not line.startswith("dkreason.live")
    ]
    assert len(lines) == 1 and lines[0].startswith(message), lines


# ---- the knowledge base as the federation changes (no network) ----------------------------


@pytest.fixture
def federation_km() -> KnowledgeManager:
    return KnowledgeManager.from_config(REPO / "examples" / "federation.toml")


def _request(kb: KnowledgeBase, formula: str) -> dict[str, set[tuple[str, str]]]:
    request = KnowledgeManager(kb).check_formula(formula)
    return {str(f.feature.key): {(t.platform, t.topic) for t in f.topics} for f in request.features}


def test_a_platform_going_offline_rederives_no_view(federation_km: KnowledgeManager) -> None:
    kb = federation_km.kb
    before = _request(kb, SPEEDING)
    kb.set_online("platform2", False)
    assert kb.rederived == []  # only the query-time rules read `online`
    assert _request(kb, SPEEDING)["Speed[car2]"] == {("platform1", "topic4")}
    kb.set_online("platform2", True)
    assert _request(kb, SPEEDING) == before


def test_a_spec_change_rederives_only_views_of_topics(federation_km: KnowledgeManager) -> None:
    from dkreason.parse.sslt import parse_text

    kb = federation_km.kb
    spec = parse_text(
        "topic uastopic9:UasMsg contains Height(uas21) = msg.height for uas21 = msg.id"
    ).specs
    added, removed = kb.replace_specs(
        "platform3", [*kb.platform("platform3").specs.values(), *spec]
    )
    assert (added, removed) == (["uastopic9"], [])
    assert set(kb.rederived) <= {
        *("topic_objects", "topic_filter", "sort_arg_at", "sort_position"),
        *("declares", "declaring", "topic_rank", "excluded_topic"),  # rules/quality.dl
    }
    assert ("platform3", "uastopic9") in _request(kb, ALTITUDE)["Altitude[uav2]"]


def test_a_platform_appearing_brings_its_mappings(tmp_path: Path) -> None:
    from dkreason.kb import make_platform
    from dkreason.parse.owl import read_ontology
    from dkreason.parse.sslt import read_specs

    full = KnowledgeBase.from_config(REPO / "examples" / "federation.toml")
    kb = KnowledgeBase(
        full.local,
        {"platform1": full.platforms["platform1"]},
        (*full.mappings, *full.pending),
        online={"platform1"},
    )
    assert _request(kb, SPEEDING)["Speed[car2]"] == {("platform1", "topic4")}
    platform2 = make_platform(
        read_ontology(REPO / "ontologies" / "platform2.owl", "platform2"),
        read_specs(REPO / "specs" / "platform2.sslt").specs,
    )
    kb.add_platform(platform2)
    assert _request(kb, SPEEDING)["Speed[car2]"] == {
        ("platform1", "topic4"),
        ("platform2", "carstopic1"),
    }


def test_an_object_joining_a_sort_reaches_the_matching(scenario: Path) -> None:
    """truck1 (a GroundVehicle) was no place to read car3's Speed; once platform 2 says it is
    an Automobile, carstopic1 serves it, and the warning goes."""
    map_car3_to_a_truck(scenario)
    kb = KnowledgeBase.from_config(scenario / "federation.toml")
    formula = "always (Speed[car3] > 60)"
    assert _request(kb, formula)["Speed[car3]"] == {("platform1", "topic5")}
    kb.add_object("platform2", "truck1", "Automobile")
    # what reads objects' sorts is derived again; the sort hierarchy and topic keys are not
    assert "member" in kb.rederived
    kept = {"rep_reach", "topic_objects", "sort_arg_at", "sort_position", "feature_candidate"}
    assert not kept & set(kb.rederived)
    request = KnowledgeManager(kb).check_formula(formula)
    assert {(t.platform, t.topic) for t in request.features[0].topics} == {
        ("platform1", "topic5"),
        ("platform2", "carstopic1"),
    }
    assert request.warnings == ()


def test_objects_a_peer_announces_at_once_are_added_in_one_step(
    scenario: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A peer announcing thousands of objects in one change cost a name index and a
    re-derivation each (quadratic): now one for the lot, and each is matched as before."""
    map_car3_to_a_truck(scenario)
    kb = KnowledgeBase.from_config(scenario / "federation.toml")
    derivations: list[None] = []
    materialize = kb.engine.materialize
    monkeypatch.setattr(kb.engine, "materialize", lambda: derivations.append(materialize()))
    trucks = [(f"t{n}", "Automobile", n) for n in range(2000)]
    iris = kb.add_objects("platform2", [*trucks, ("truck1", "Automobile", None), trucks[0]])
    assert len(derivations) == 1 and len(set(iris)) == 2001
    assert {i for i in kb.platform("platform2").ontology.individuals if "#t" in i} >= set(
        iris[:2000]
    )
    request = KnowledgeManager(kb).check_formula("always (Speed[car3] > 60)")
    assert ("platform2", "carstopic1") in {
        (t.platform, t.topic) for t in request.features[0].topics
    }


def test_a_node_publishes_json_lines_from_its_standard_input(
    procs: Processes, tmp_path: Path
) -> None:
    (tmp_path / "monitor.toml").write_text('local = "platform1"\n[platforms.platform1]\n')
    port = free_port()
    monitor = procs.start(
        "monitor",
        "--live",
        "--config",
        str(tmp_path / "monitor.toml"),
        "--listen",
        f"tcp/127.0.0.1:{port}",
        "--until",
        "3",
        "--json",
        "always (Speed[car1] < 100)",
    )
    events, seen = lines_of(monitor), list[dict[str, Any]]()
    node = procs.start(
        "serve",
        "--config",
        str(REPO / "examples" / "live" / "platform1.toml"),
        "--connect",
        f"tcp/127.0.0.1:{port}",
        "--source",
        "-",
        stdin=subprocess.PIPE,
    )
    wait_for(events, seen, event="subscribed", platform="platform1", topic="topic3")
    subscription_known(port, "dkreason/platform1/topic/topic3")
    assert node.stdin is not None
    for t in range(6):  # the stream clock passes --until at 4: the monitor stops
        node.stdin.write(
            json.dumps({"topic": "/platform1/topic3", "time": t, "msg": {"id": 1, "spd": 50.0 + t}})
            + "\n"
        )
        node.stdin.flush()
    assert monitor.wait(timeout=20) == 0
    node.stdin.close()
    while (event := events.get(timeout=5)) is not None:
        seen.append(event)
    (verdict,) = [e for e in seen if "verdict" in e]
    assert (verdict["verdict"], verdict["time"], verdict["at_end"]) == (True, 3, True)


class InProcess:
    """Platforms 1 and 2 of the thesis scenario, with car3 mapped to platform 2's truck1 (a
    GroundVehicle), as nodes in this process, and a monitor of Speed[car3] over them."""

    def __init__(self, scenario: Path, sign: Any = None, **options: Any) -> None:
        """`sign`: platform 1's signing key (signing.Signer); `options`: the monitor's."""
        from dkreason.live.monitor import LiveMonitor
        from dkreason.live.session import open_session
        from dkreason.stream.policy import StreamPolicy

        self.scenario = scenario
        map_car3_to_a_truck(scenario)
        (scenario / "monitor.toml").write_text(
            'local = "platform1"\n[platforms.platform1]\n[platforms.platform2]\n'
            '[[mappings]]\nsource = "platform1"\ntarget = "platform2"\n'
            'file = "mappings/platform1-platform2.cowl.xml"\n'
        )
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.sessions = [open_session([], [self.endpoint])]
        self.port = int(self.endpoint.rsplit(":", 1)[1])
        self.nodes = [self.node(1, sign=sign), self.node(2)]
        self.monitor = LiveMonitor(
            KnowledgeManager.from_config(scenario / "monitor.toml", live=True),
            ["always (Speed[car3] > 60)"],
            StreamPolicy(),
            self.sessions[0],
            wait=10,
            **options,
        )

    def node(self, n: int, sign: Any = None) -> Any:
        from dkreason.live.serve import PlatformNode
        from dkreason.live.session import open_session

        config = self.scenario / f"p{n}.toml"
        config.write_text(
            f'[platforms.platform{n}]\nontology = "ontologies/platform{n}.owl"\n'
            f'specs = "specs/platform{n}.sslt"\n'
        )
        self.sessions.append(open_session([self.endpoint], []))
        return PlatformNode(KnowledgeManager.from_config(config), self.sessions[-1], sign=sign)

    def run(self, steps: list[tuple[set[tuple[str, str, str, str]], Any]]) -> list[tuple[str, ...]]:
        """The monitor's changes, taking each step once the changes it waits for are seen."""
        from dkreason.live.change import Change

        changes: list[tuple[str, ...]] = []
        try:
            for event in self.monitor.run(duration=20):
                if isinstance(event, Change):  # not the end verdict
                    changes.append((event.event, event.platform, event.topic, event.feature))
                    if steps and steps[0][0] <= set(changes):
                        steps.pop(0)[1]()
        finally:
            for node in self.nodes:
                node.close()
            for session in self.sessions:
                session.close()
        return changes


STARTED = {("joined", "platform2", "", ""), ("subscribed", "platform1", "topic5", "Speed[car3]")}
CARSTOPIC1 = ("subscribed", "platform2", "carstopic1", "Speed[car3]")


def test_objects_and_specs_a_node_announces_reach_a_running_monitor(scenario: Path) -> None:
    """Through the Python API: platform 2 says truck1 is an Automobile, then drops a topic;
    the running monitor subscribes and unsubscribes accordingly."""
    fed = InProcess(scenario)
    changes = fed.run(
        [
            (STARTED, lambda: fed.nodes[1].add_object("truck1", "Automobile")),
            ({CARSTOPIC1}, lambda: fed.nodes[1].remove_topic("carstopic1")),
            ({("unsubscribed", "platform2", "carstopic1", "")}, fed.monitor.stop.set),
        ]
    )
    assert CARSTOPIC1 in changes
    assert ("unsubscribed", "platform2", "carstopic1", "") in changes
    assert not any(c[0] == "source_lost" for c in changes)  # topic5 still serves Speed[car3]


def test_an_object_joining_the_live_federation_is_monitored_from_its_arrival(
    scenario: Path,
) -> None:
    """Platform 1 announces a third UAV while the monitor runs: the monitor says its instance
    of `forall x in UAV` is judged from then on, and reports its violation; uav1's and
    uav2's instances go on as they were."""
    from dkreason.live.change import Change
    from dkreason.progress import Verdict

    def altitudes(second: float, **alt: float) -> None:
        for uav, value in alt.items():
            t = int(second * 10**9)
            node.publish("topic2", {"id": int(uav[-1]), "alt": value}, t, t)

    events: list[Any] = []
    with platform1_live(scenario, [ALTITUDE]) as (node, monitor, sessions):
        for event in monitor.run(duration=30):
            events.append(event)
            if isinstance(event, Change) and (event.event, event.topic) == (
                "subscribed",
                "topic2",
            ):  # once the subscription reached the node (on a loaded machine: seconds later)
                heard(sessions[1].declare_publisher("dkreason/platform1/topic/topic2")).undeclare()
                altitudes(1, uav1=100.0, uav2=100.0)
                altitudes(1.5, uav1=100.0, uav2=100.0)
                node.add_object("uav3", "UAV")
            elif isinstance(event, Change) and event.event == "instance":
                altitudes(2, uav3=5.0, uav1=100.0)
                altitudes(3, uav1=100.0)
            elif isinstance(event, Verdict) and not event.update:
                monitor.stop.set()
    (joined,) = [e for e in events if isinstance(e, Change) and e.event == "instance"]
    assert (joined.feature, joined.detail) == ("x = uav3", ALTITUDE)
    verdict, *_ = [e for e in events if isinstance(e, Verdict)]
    assert (verdict.formula, verdict.verdict, verdict.time) == (ALTITUDE, False, 2)
    assert verdict.witness == (
        "x = uav3 violated at t+1 s: Altitude[uav3] > 10 was false at t+1 s (Altitude[uav3] = 5.0)"
    )
    assert verdict.instances is not None
    assert [(i.name, i.status) for i in verdict.instances] == [
        ("x = uav1", "open"),
        ("x = uav2", "open"),
        ("x = uav3", "violated"),
    ]


def test_a_platform_back_with_another_ontology_replaces_its_knowledge(scenario: Path) -> None:
    """Platform 2 restarts with a new sort, Truck ⊑ Automobile, and truck1 a Truck: no change
    of specs or objects could say that, so the monitor replaces what it knew of platform 2,
    and reads Speed[car3] from carstopic1."""
    from .test_federation import P2, add_to_ontology

    fed = InProcess(scenario)

    def restart_platform2() -> None:
        fed.nodes[1].close()
        fed.sessions.pop().close()
        add_to_ontology(
            scenario / "ontologies" / "platform2.owl",
            f'<owl:Class rdf:about="{P2}Truck"><rdfs:subClassOf '
            f'rdf:resource="{P2}Automobile"/></owl:Class>'
            f'<rdf:Description rdf:about="{P2}truck1">'
            f'<rdf:type rdf:resource="{P2}Truck"/></rdf:Description>',
        )
        fed.nodes[1] = fed.node(2)

    changes = fed.run([(STARTED, restart_platform2), ({CARSTOPIC1}, fed.monitor.stop.set)])
    assert [c[:2] for c in changes if c[1] == "platform2" and c[0] in ("joined", "left")] == [
        ("joined", "platform2"),
        ("left", "platform2"),
        ("joined", "platform2"),
    ]
    assert CARSTOPIC1 in changes


def test_a_platform_removed_and_added_again_matches_as_before(
    federation_km: KnowledgeManager,
) -> None:
    kb = federation_km.kb
    before = _request(kb, SPEEDING)
    platform2 = kb.remove_platform("platform2")
    assert "platform2" not in kb.platforms
    assert _request(kb, SPEEDING)["Speed[car2]"] == {("platform1", "topic4")}
    kb.add_platform(platform2)
    assert _request(kb, SPEEDING) == before
    with pytest.raises(DkError, match="local platform"):
        kb.remove_platform("platform1")


def test_signed_samples_reject_an_injector(procs: Processes, tmp_path: Path) -> None:
    """A node signs with --sign; a monitor given its key with --trust rejects and counts what
    anyone else puts on the node's keys, and keeps the signed verdict."""
    import zenoh
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from dkreason.live.session import open_session

    key = Ed25519PrivateKey.generate()
    (tmp_path / "p1.pem").write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    (tmp_path / "p1.pub.pem").write_bytes(
        key.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
        )
    )
    (tmp_path / "keys.toml").write_text('platform1 = "p1.pub.pem"\n')
    (tmp_path / "monitor.toml").write_text('local = "platform1"\n[platforms.platform1]\n')
    port = free_port()
    monitor = procs.start(
        "monitor",
        "--live",
        "--config",
        str(tmp_path / "monitor.toml"),
        "--listen",
        f"tcp/127.0.0.1:{port}",
        "--until",
        "3",
        "--json",
        "--trust",
        str(tmp_path / "keys.toml"),
        "always (Speed[car1] < 100)",
    )
    events, seen, log = lines_of(monitor), list[dict[str, Any]](), log_of(monitor)
    node = procs.start(
        "serve",
        "--config",
        str(REPO / "examples" / "live" / "platform1.toml"),
        "--connect",
        f"tcp/127.0.0.1:{port}",
        "--source",
        "-",
        "--sign",
        str(tmp_path / "p1.pem"),
        stdin=subprocess.PIPE,
    )
    wait_for(events, seen, event="subscribed", platform="platform1", topic="topic3")
    rogue = open_session([f"tcp/127.0.0.1:{port}"], [])
    try:
        bad = heard(
            rogue.declare_publisher(
                "dkreason/platform1/topic/topic3", congestion_control=zenoh.CongestionControl.BLOCK
            )
        )
        for t in range(3):  # an injector on the node's own key, unsigned and forged
            bad.put(json.dumps({"valid": t * 10**9, "msg": {"id": 1, "spd": 500.0}}).encode())
            bad.put(
                json.dumps({"valid": t * 10**9, "msg": {"id": 1, "spd": 501.0}}).encode(),
                attachment=b"\0" * 64,
            )
        logged(log, "unsigned sample", "bad signature")  # taken, judged, dropped: then data
        assert node.stdin is not None
        for t in range(6):
            node.stdin.write(
                json.dumps(
                    {"topic": "/platform1/topic3", "time": t, "msg": {"id": 1, "spd": 50.0 + t}}
                )
                + "\n"
            )
            node.stdin.flush()
        assert monitor.wait(timeout=30) == 0
    finally:
        rogue.close()
    node.stdin.close()
    while (event := events.get(timeout=5)) is not None:
        seen.append(event)
    (verdict,) = [e for e in seen if "verdict" in e]
    assert verdict["verdict"] is True
    assert "Traceback" not in "".join(log)


# ---- issue 27: peers cannot blind the monitor -------------------------------------------------


def test_a_knowledge_reply_past_the_limits_refuses_that_platform_and_the_rest_is_monitored(
    scenario: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Platform 2 answers with more topics than the monitor takes (a 100,000-topic reply in
    8 MB took 2 GB and 150 s): it is refused in one line, and platform 1's data is judged."""
    from dkreason.live.change import Change
    from dkreason.live.wire import Limits
    from dkreason.progress import Verdict

    specs = scenario / "specs" / "platform2.sslt"
    specs.write_text(
        specs.read_text()
        + "".join(
            f"topic extra{n}:AutomobileMsg contains Speed(Automobile) = msg.speed "
            f"for some Automobile = msg.id\n"
            for n in range(20)
        )
    )
    fed = InProcess(scenario, limits=Limits(topics=10))  # platform 1 has 9, platform 2 23
    events: list[Any] = []
    try:
        for event in fed.monitor.run(duration=30):
            events.append(event)
            if isinstance(event, Change) and (event.event, event.topic) == ("subscribed", "topic5"):
                subscription_known(fed.port, "dkreason/platform1/topic/topic5")
                for t in (1, 2):
                    fed.nodes[0].publish("topic5", {"id": 3, "spd": 50.0}, t * 10**9)
            elif isinstance(event, Verdict):
                fed.monitor.stop.set()
    finally:
        for node in fed.nodes:
            node.close()
        for session in fed.sessions:
            session.close()
    verdict = next(e for e in events if isinstance(e, Verdict))
    assert (verdict.verdict, verdict.time) == (False, 1)
    assert not [e for e in events if isinstance(e, Change) and e.platform == "platform2"]
    assert fed.monitor.rejected == {("platform2", "knowledge", "limit"): 1}
    (line,) = [r.getMessage() for r in caplog.records if "rejected knowledge" in r.getMessage()]
    assert line.endswith("platform2's topics: more than 10 (--max-peer-topics)")


class _Replies:
    """A session whose every query is answered by `answers` (what → payload), signed by
    `sign` (challenge, key expression, payload → attachment), and that declares nothing: a
    LiveMonitor's knowledge side, without a network."""

    def __init__(self, answers: dict[str, bytes], sign: Any = None) -> None:
        self.answers, self.sign = answers, sign

    def liveliness(self) -> _Replies:
        return self

    def declare_subscriber(self, *_: Any, **__: Any) -> Any:
        return self

    def get(self, key: str, attachment: bytes = b"", **_: Any) -> list[_Reply]:
        payload = self.answers[key.rsplit("/", 1)[1]]
        signed = None if self.sign is None else _Bytes(self.sign(attachment, key, payload))
        return [_Reply(_Sample(_Bytes(payload), signed))]


@dataclass
class _Bytes:  # zenoh's ZBytes, Sample and Reply, as far as a monitor reads them
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class _Sample:
    payload: _Bytes
    attachment: _Bytes | None


@dataclass
class _Reply:
    ok: _Sample


def test_a_hundred_thousand_topics_are_refused_before_they_are_parsed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from dkreason.errors import WireError
    from dkreason.live import wire
    from dkreason.live.monitor import LiveMonitor
    from dkreason.stream.policy import StreamPolicy

    def parse_text(*_: Any) -> Any:
        raise AssertionError("parsed before it was counted")

    monkeypatch.setattr("dkreason.parse.sslt.parse_text", parse_text)
    sslt = "".join(f"topic t{n}:CarMsg contains Speed(car1) = msg.spd\n" for n in range(100_000))
    objects = {
        f"http://x.org/o{n}": {"sorts": ["http://x.org/Car"], "id": n} for n in range(60_000)
    }
    monitor = LiveMonitor(
        KnowledgeManager.from_config(REPO / "examples" / "live" / "monitor.toml", live=True),
        ["true"],
        StreamPolicy(),
        _Replies({"specs": wire.encode({"sslt": sslt}), "objects": wire.encode(objects)}),
    )
    with pytest.raises(WireError, match=r"platform2's topics: more than 10,000"):
        monitor._specs("platform2")
    with pytest.raises(WireError, match=r"platform2's objects: more than 50,000"):
        monitor._objects("platform2")


def _keys(tmp_path: Path, text: str) -> Path:
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    (tmp_path / "p1.pub.pem").write_bytes(
        Ed25519PrivateKey.generate()
        .public_key()
        .public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
    )
    (tmp_path / "keys.toml").write_text(text)
    return tmp_path / "keys.toml"


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ('Platform1 = "p1.pub.pem"\n', "'Platform1' is not a platform of the config (did you mean"),
        ('platform9 = "p1.pub.pem"\n', "'platform9' is not a platform of the config"),
        ("", "names no platform's key"),
        ("# every key commented out\n", "names no platform's key"),
    ],
)
def test_trust_fails_closed_on_a_keys_file_naming_no_configured_platform(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], keys: str, message: str
) -> None:
    """A misspelt name left its platform unsigned and an injected sample was taken: now the
    monitor does not start (one line, exit 2)."""
    (tmp_path / "monitor.toml").write_text('local = "platform1"\n[platforms.platform1]\n')
    code = main(
        [
            "monitor",
            "--live",
            "--config",
            str(tmp_path / "monitor.toml"),
            "--trust",
            str(_keys(tmp_path, keys)),
            "always (Speed[car1] < 100)",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err


def test_trust_given_to_the_api_fails_closed_too(scenario: Path) -> None:
    from dkreason.live.monitor import LiveMonitor
    from dkreason.stream.policy import StreamPolicy

    km = KnowledgeManager.from_config(REPO / "examples" / "live" / "monitor.toml", live=True)
    for trust, message in (({}, "names no platform"), ({"Platform2": None}, "did you mean")):
        with pytest.raises(DkError, match=message):
            LiveMonitor(km, ["true"], StreamPolicy(), _Replies({}), trust=trust)


def test_a_platform_that_signs_is_known_only_from_a_reply_signed_for_this_question() -> None:
    """Knowledge replies were not signed: anyone answering as a platform was believed.  A
    reply must now be signed by the platform's key for the challenge the monitor attached
    (a reply recorded earlier answers another), and it says the node's nonce."""
    import os

    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from dkreason.errors import WireError
    from dkreason.live import wire
    from dkreason.live.monitor import LiveMonitor
    from dkreason.live.signing import Signer
    from dkreason.stream.policy import StreamPolicy

    key = Ed25519PrivateKey.generate()
    node, impostor = Signer(key, os.urandom(16)), Signer(Ed25519PrivateKey.generate(), b"x" * 16)
    km = KnowledgeManager.from_config(REPO / "examples" / "live" / "monitor.toml", live=True)
    specs = {"specs": wire.encode({"sslt": "topic t:CarMsg contains Speed(car1) = msg.spd\n"})}

    def asked(sign: Any) -> LiveMonitor:
        session = _Replies(specs, sign)
        trust = {"platform1": key.public_key()}
        monitor = LiveMonitor(km, ["true"], StreamPolicy(), session, trust=trust)
        monitor._specs("platform1")
        return monitor

    assert asked(node.reply).nonces == {"platform1": node.nonce}
    for sign, why in (
        (None, "unsigned reply"),
        (lambda _, k, p: node.reply(b"an earlier question", k, p), "bad signature on the reply"),
        (impostor.reply, "bad signature on the reply"),
        (lambda c, k, p: node.sample(k, p), "bad signature on the reply"),  # not a reply's
    ):
        with pytest.raises(WireError, match=why):
            asked(sign)


def test_a_signed_sample_replayed_from_another_run_is_rejected_and_counted(
    scenario: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A sample platform 1 signed in an earlier run, put again by anyone, verifies but carries
    that run's nonce: rejected as a replay, counted, said in the summary; the node's samples of
    this run are taken."""
    import os

    import zenoh
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from dkreason.live import wire
    from dkreason.live.change import Change
    from dkreason.live.session import open_session
    from dkreason.live.signing import Signer
    from dkreason.progress import Verdict

    key = Ed25519PrivateKey.generate()
    earlier, now = Signer(key, os.urandom(16)), Signer(key, os.urandom(16))
    fed = InProcess(scenario, sign=now, trust={"platform1": key.public_key()})
    rogue = open_session([fed.endpoint], [])
    topic5 = wire.key("platform1", "topic", "topic5")
    replayed = wire.encode({"valid": 10**9, "available": 10**9, "msg": {"id": 3, "spd": 50.0}})

    def attack_then_publish() -> None:
        bad = heard(
            rogue.declare_publisher(topic5, congestion_control=zenoh.CongestionControl.BLOCK)
        )
        bad.put(replayed, attachment=earlier.sample(topic5, replayed))
        deadline = time.monotonic() + 30
        while ("platform1", "sample", "replay") not in fed.monitor.rejected:
            assert time.monotonic() < deadline, "the replay was not seen"
            time.sleep(0.01)
        subscription_known(fed.port, topic5)
        for t in (1, 2, 3):
            fed.nodes[0].publish("topic5", {"id": 3, "spd": 70.0}, t * 10**9)

    events: list[Any] = []
    try:
        for event in fed.monitor.run(until=Fraction(2), duration=60):
            events.append(event)
            if isinstance(event, Change) and (event.event, event.topic) == ("subscribed", "topic5"):
                threading.Thread(target=attack_then_publish, daemon=True).start()
    finally:
        rogue.close()
        for node in fed.nodes:
            node.close()
        for session in fed.sessions:
            session.close()
    assert fed.monitor.rejected == {("platform1", "sample", "replay"): 1}
    assert fed.monitor.received == 2  # this run's samples up to 2 s
    assert [e.verdict for e in events if isinstance(e, Verdict)] == [True]  # never below 60
    assert "in all, rejected 1 sample from platform1 (replay)" in caplog.text


# ---- the inbox from zenoh's threads -----------------------------------------------------------


def test_the_inbox_loses_nothing_and_keeps_each_threads_order() -> None:
    inbox, n, threads = Inbox(), 20_000, 4
    producers = [
        threading.Thread(target=lambda k=k: [inbox.put((k, i)) for i in range(n)])
        for k in range(threads)
    ]
    for t in producers:
        t.start()
    got: list[tuple[int, int]] = []
    deadline = time.monotonic() + 60
    while len(got) < n * threads and time.monotonic() < deadline:
        got += inbox.drain(0.05)
    for t in producers:
        t.join()
    assert len(got) == n * threads
    for k in range(threads):
        assert [i for j, i in got if j == k] == list(range(n))


def test_a_sleeping_consumer_wakes_for_an_event() -> None:
    inbox = Inbox()
    threading.Timer(0.05, inbox.put, ["hello"]).start()
    assert inbox.drain(60) == ["hello"]  # returns when it arrives, not after 60 s
    assert inbox.drain(0) == []


def test_a_full_inbox_holds_the_producer_then_refuses() -> None:
    inbox = Inbox(limit=3)
    assert all(inbox.put(i, timeout=0.01) for i in range(3))
    assert not inbox.put(3, timeout=0.01)  # no room within the wait: dropped
    threading.Timer(0.05, inbox.drain, [0]).start()
    assert inbox.put(4, timeout=60)  # room made by a drain wakes it
    assert inbox.drain(0) == [4]


# ---- one run loop for both live monitors (no network) ----------------------------------------


class ScriptedFeed:
    """A live monitor's side of the loop, scripted: each event in its inbox is a sample of
    Speed[car1] (stream time in s, value), and the stream clock is the newest sample's.  As
    the federation's monitor does, it takes no sample past `end` (ns)."""

    def __init__(
        self,
        processor: Any,
        samples: list[tuple[int, float]],
        over: bool = False,
        end: int | None = None,
    ) -> None:
        self.inbox, self.stop, self.processor = Inbox(), threading.Event(), processor
        self.newest: int | None = None
        self.ended, self.end, self.closed, self.ticks = over, end, False, 0
        for sample in samples:
            self.inbox.put(sample)

    def handle(self, event: tuple[int, float]) -> list[Any]:
        t = event[0] * 10**9
        if self.end is None or t <= self.end:
            self.processor.put("platform1/topic3", t, t, (event[1], 1))
        self.newest = t
        return []

    def now(self) -> int | None:
        return self.newest

    def watermark(self) -> int | None:
        return self.newest

    def idle(self) -> float:
        return 0.0

    def over(self) -> bool:
        return self.ended and not self.inbox.items

    def tick(self) -> None:
        self.ticks += 1

    def close(self) -> None:
        self.closed = True


def _engine(formula: str) -> tuple[Any, Any]:
    from dkreason.live.loop import LiveSource
    from dkreason.monitor import Monitor
    from dkreason.stream.policy import StreamPolicy

    km = KnowledgeManager.from_config(REPO / "examples" / "federation.toml")
    monitor = Monitor(km.plan([formula]), km.request, StreamPolicy())
    return monitor, monitor.start(LiveSource())


def test_the_loop_ends_once_the_stream_clock_passes_until() -> None:
    from dkreason.live import loop
    from dkreason.progress import Verdict

    monitor, processor = _engine("always (Speed[car1] < 100)")
    until = 5 * 10**9
    feed = ScriptedFeed(processor, [(t, 50.0) for t in range(10)] + [(10, 150.0)], end=until)
    events = list(loop.run(monitor, processor, feed, until, None))
    # the samples up to 5 s judged, at the end; the bad one at 10 s never reached a state
    assert [(e.verdict, e.time, e.at_end) for e in events if isinstance(e, Verdict)] == [
        (True, 5, True)
    ]
    assert feed.closed and feed.ticks == 1  # one pass took every sample, the next ended


def test_the_loop_ends_when_nothing_more_comes_or_when_stopped() -> None:
    from dkreason.live import loop
    from dkreason.progress import Verdict

    monitor, processor = _engine("always (Speed[car1] < 100)")
    feed = ScriptedFeed(processor, [(0, 50.0), (1, 150.0), (2, 50.0)], over=True)
    (verdict,) = list(loop.run(monitor, processor, feed, None, None))
    assert isinstance(verdict, Verdict) and (verdict.verdict, verdict.time) == (False, 1)

    monitor, processor = _engine("always (Speed[car1] < 100)")
    feed = ScriptedFeed(processor, [(0, 50.0)])
    feed.stop.set()  # before any event is taken
    (verdict,) = list(loop.run(monitor, processor, feed, None, None))
    assert isinstance(verdict, Verdict) and verdict.verdict is None
    assert feed.inbox.items and feed.closed


# ---- the live monitor takes a knowledge manager; nothing is made while it runs -------------


def test_a_live_knowledge_base_awaits_the_platforms_its_config_gives_no_files() -> None:
    from dkreason.errors import ParseError

    config = REPO / "examples" / "live" / "monitor.toml"
    km = KnowledgeManager.from_config(config, live=True)
    assert (km.local, km.platforms, len(km.kb.pending)) == ("platform1", [], 2)  # the
    # mappings wait for both of their platforms
    at_hand = KnowledgeManager.from_config(REPO / "examples" / "federation.toml", live=True)
    assert at_hand.platforms == ["platform1", "platform2", "platform3"]
    assert not any(at_hand.kb.is_online(p) for p in at_hand.platforms)  # until they appear
    with pytest.raises(ParseError, match="has no ontology file"):
        KnowledgeManager.from_config(config)


def test_a_live_monitor_has_every_attribute_from_construction(scenario: Path) -> None:
    """The engine and its stream processor are None until the local platform is there, and
    a run adds no attribute (the CLI reads `monitor.processor` as it is)."""
    fed = InProcess(scenario)
    before = dict(vars(fed.monitor))
    fed.run([(STARTED, fed.monitor.stop.set)])
    assert before["monitor"] is None and before["processor"] is None
    assert set(vars(fed.monitor)) == set(before)
    assert fed.monitor.processor is not None


ONE, TWO = ("platform1/topic1",), ("platform1/topic2",)


def heard_all(session: Any, topics: set[str]) -> None:
    """Platform 1's `topics` each heard by the monitor's subscriber before anything is sent."""
    from dkreason.live import wire

    for topic in sorted(topics):
        heard(session.declare_publisher(wire.key("platform1", "topic", topic))).undeclare()


def send(
    node: Any, session: Any, topics: tuple[str, ...], tick: tuple[str, ...], tenths: range
) -> None:
    """uav1's altitude on platform 1's `topics` at each tenth of a second; the `tick` topics
    send only their clock (it goes on: nothing of them before t is missing)."""
    from dkreason.live import wire

    for n in tenths:
        t = n * 10**8
        for topic in topics:
            node.publish(topic, {"id": 1, "alt": 50.0}, t, t)
        for topic in tick:
            session.put(wire.key("platform1", "topic", topic), wire.encode({"clock": t}))


@pytest.mark.parametrize(
    ("best_source", "read", "aside"),
    [(False, (*ONE, *TWO), TWO), (True, ONE, TWO)],
    ids=["merged", "best-source"],
)
def test_a_platforms_topic_that_stops_is_set_aside_and_taken_back_when_it_returns(
    scenario: Path, best_source: bool, read: tuple[str, ...], aside: tuple[str, ...]
) -> None:
    """Platform 1 sends uav1's altitude on topic1 and topic2 (both declared 10 Hz); topic1's
    samples stop while its clock goes on: the monitor reads topic2 alone, keeping topic1
    subscribed, and reads topic1 again once it sends.  With --best-source topic1 alone is
    read at first, topic2 subscribed beside it (ranked next).  Each step waits on the event
    before it; the verdict is never restarted."""
    from dkreason.live.change import Change
    from dkreason.monitor import Rerouted
    from dkreason.progress import Verdict
    from dkreason.stream.policy import StreamPolicy

    from .test_quality import TEN_HZ, declare

    declare(scenario, *TEN_HZ)
    subscribed: set[str] = set()
    events: list[Any] = []
    policy = StreamPolicy(best_source=best_source)
    with platform1_live(scenario, ["always (Altitude[uav1] > 1)"], policy) as (
        node,
        monitor,
        sessions,
    ):
        for event in monitor.run(duration=30):
            events.append(event)
            if isinstance(event, Change) and event.event == "subscribed":
                subscribed.add(event.topic)
                if subscribed == {"topic1", "topic2"}:
                    heard_all(sessions[1], subscribed)
                    send(node, sessions[1], ("topic1", "topic2"), (), range(1, 11))
                    send(node, sessions[1], ("topic2",), ("topic1",), range(11, 21))
            elif isinstance(event, Rerouted) and event.aside:
                send(node, sessions[1], ("topic1", "topic2"), (), range(21, 26))
            elif isinstance(event, Rerouted):
                monitor.stop.set()
    moves = [e for e in events if isinstance(e, Rerouted)]
    assert [(m.source, m.aside, m.before, m.after) for m in moves] == [
        ("platform1/topic1", True, read, aside),
        ("platform1/topic1", False, aside, read),
    ]
    assert moves[1].time == 2.1
    roles = {e.topic: e.detail for e in events if isinstance(e, Change) and e.event == "subscribed"}
    assert roles == {"topic1": "", "topic2": "standing by" if best_source else ""}
    assert not any(isinstance(e, Change) and e.event == "unsubscribed" for e in events)
    (verdict,) = [e for e in events if isinstance(e, Verdict)]
    assert (verdict.verdict, verdict.at_end) == (True, True)


def test_a_live_monitor_matches_with_its_max_delay_as_the_knowledge_changes(
    scenario: Path,
) -> None:
    """With --max-delay 100ms, topic2 (declaring a 200 ms delay) is never subscribed, nor a
    topic announced later that declares 300 ms; one announced after it declaring 10 ms is."""
    from dkreason.live.change import Change
    from dkreason.stream.policy import StreamPolicy

    from .test_quality import LAGGING, SLOW, declare

    declare(scenario, SLOW, LAGGING)
    later = "topic {}:UavMsg [delay {}] contains Altitude(uav1) = msg.alt for uav1 = msg.id"
    subscribed: list[str] = []
    policy = StreamPolicy(max_delay=Fraction(1, 10))
    with platform1_live(scenario, ["always (Altitude[uav1] > 1)"], policy) as (node, monitor, _):
        for event in monitor.run(duration=30):
            if isinstance(event, Change) and event.event == "subscribed":
                subscribed.append(event.topic)
                if event.topic == "topic1":
                    node.add_topic(later.format("lagging", "300ms"))
                    node.add_topic(later.format("prompt", "10ms"))
                elif event.topic == "prompt":
                    monitor.stop.set()
    assert subscribed == ["topic1", "prompt"]


def test_a_best_topic_that_never_sends_is_set_aside_from_the_start_and_its_standby_feeds_at_once(
    scenario: Path, tmp_path: Path
) -> None:
    """Under --best-source uav1's altitude is read from topic1 (declared 10 Hz), which never
    sends (its clock goes on); topic2, standing by, does.  Counted from the start of the
    stream, topic1's silence passes three periods and it is set aside; topic2's newest
    sample feeds the altitude at once, so stopping right then still judges it (as a replay
    of the same data does)."""
    from dkreason.live.change import Change
    from dkreason.monitor import Rerouted
    from dkreason.progress import Verdict
    from dkreason.stream.policy import StreamPolicy

    from .test_quality import TEN_HZ, declare, replayed, topic2_alone

    declare(scenario, *TEN_HZ)
    subscribed: set[str] = set()
    events: list[Any] = []
    policy = StreamPolicy(best_source=True)
    with platform1_live(scenario, ["always (Altitude[uav1] > 1)"], policy) as (
        node,
        monitor,
        sessions,
    ):
        for event in monitor.run(duration=30):
            events.append(event)
            if isinstance(event, Change) and event.event == "subscribed":
                subscribed.add(event.topic)
                if subscribed == {"topic1", "topic2"}:
                    heard_all(sessions[1], subscribed)
                    send(node, sessions[1], ("topic2",), ("topic1",), range(1, 11))
            elif isinstance(event, Rerouted):
                monitor.stop.set()
    (move,) = [e for e in events if isinstance(e, Rerouted)]
    assert (move.source, move.aside, move.before, move.after) == (
        "platform1/topic1",
        True,
        ONE,
        TWO,
    )
    assert move.reason.startswith("no sample since the start (")
    assert 0.4 < move.time <= 1.0  # (when the stream clock passed three periods)
    (verdict,) = [e for e in events if isinstance(e, Verdict)]
    assert verdict.verdict is True
    offline = KnowledgeManager.from_config(scenario / "single.toml")
    again = replayed(offline, topic2_alone(tmp_path), best_source=True)
    assert [e.verdict for e in again if isinstance(e, Verdict)] == [True]
    assert [(e.before, e.after) for e in again if isinstance(e, Rerouted)] == [(ONE, TWO)]
