"""Fleets the right way (issue 28, items 8 and 10): docs/own-robot.md's walk-through of two
robots (examples/turtles: per-robot objects, one specs file under namespaces) run as written, topics
shown by the ROS names they resolve to, and a federation recorded under its topics' bare
names bound where no other platform's spec uses the name."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from dkreason.cli import main
from dkreason.model import TopicMatch
from dkreason.stream.binding import recording_names
from dkreason.stream.recording import Row, write_recording

from .conftest import REPO

TURTLES = REPO / "examples" / "turtles"
FLEET = str(TURTLES / "fleet.toml")
S = 10**9


@pytest.fixture(scope="module")
def turtles(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The walk-through's recording, as examples/turtles/simulate.py writes it."""
    target = tmp_path_factory.mktemp("turtles") / "rosbag2_2026_11_24"
    subprocess.run(
        [sys.executable, str(TURTLES / "simulate.py"), str(target)],
        check=True,
        capture_output=True,
    )
    return str(target)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main(list(argv))
    return code, capsys.readouterr().out


def test_the_walk_through_binds_each_robots_topics_under_its_namespace(
    turtles: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out = run(capsys, "info", "--config", FLEET, turtles)
    assert code == 0
    assert "turtle1/pose (turtlesim/Pose) ← /turtle1/pose" in out
    assert "turtle2/pose (turtlesim/Pose) ← /turtle2/pose" in out


def test_match_shows_each_topic_by_the_ros_name_it_resolves_to(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Both robots' topic is `pose` in the one specs file: the request says which is which
    (it printed `Topic: pose` twice)."""
    formula = "forall r in Robot: always (X[r] < 9.5)"
    _, out = run(capsys, "match", "--config", FLEET, formula)
    assert "Feature: X[turtle1]\nTopics to merge:\n  Topic: /turtle1/pose (platform turtle1" in out
    assert "Feature: X[turtle2]\nTopics to merge:\n  Topic: /turtle2/pose (platform turtle2" in out
    _, out = run(capsys, "match", "--json", "--config", FLEET, formula)
    topics = [t for f in json.loads(out)["features"] for t in f["topics"]]
    assert [(t["topic"], t["ros_name"]) for t in topics] == [
        ("pose", "/turtle1/pose"),
        ("pose", "/turtle2/pose"),
    ]


def test_each_robot_is_judged_on_its_own_data(
    turtles: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """turtle1 ends at x = 9.5019; turtle2 stays in the middle.  With one shared object `me`
    (the walk-through's old pattern) turtle1's pose also judged turtle2."""
    code, out = run(
        capsys,
        "monitor",
        "--json",
        "--config",
        FLEET,
        "--source",
        turtles,
        "forall r in Robot: always (X[r] < 9.5)",
        "always (X[turtle2] < 9.5)",
    )
    every, update, turtle2 = [json.loads(line) for line in out.splitlines()]
    assert code == 1
    assert every["verdict"] is False and every["t"] == 19.9
    assert "X[turtle1] = 9.50189971923828" in every["witness"]
    assert turtle2["verdict"] is True
    # the robots judged one by one: turtle1 violated, turtle2 held (said once it settled)
    assert update["update"] and [
        (i["bindings"]["r"], i["status"]) for i in update["instances"]
    ] == [
        ("turtle1", "violated"),
        ("turtle2", "held"),
    ]


# ---- bare names (item 10) -------------------------------------------------------------------

FEDERATION = REPO / "examples" / "federation.toml"
MSGS = REPO / "examples" / "traffic" / "msg" / "dkreason_msgs" / "msg"
TYPES = {f"dkreason_msgs/msg/{p.stem}": p.read_text() for p in MSGS.glob("*.msg")}


def bare_federation(path: Path) -> Path:
    """The traffic scenario recorded under its topics' own names: platform 1's car2 (topic4)
    for 5 s, then only platform 2's carstopic1, where car2 is car12, speeding for 400 s;
    platform 3's uastopic5 gives uav2's altitude (as uas21's Alt)."""
    rows: list[Row] = [
        ("topic4", "dkreason_msgs/msg/CarMsg", t * S, {"id": 2, "spd": 70.0}) for t in range(5)
    ]
    rows += [
        (
            "carstopic1",
            "dkreason_msgs/msg/AutomobileMsg",
            t * S,
            {"header": {"stamp": t}, "id": 12, "speed": 70.0, "position": 0.0},
        )
        for t in range(400)
    ]
    rows += [
        (
            "uastopic5",
            "dkreason_msgs/msg/UasMsg",
            t * S,
            {"header": {"stamp": t}, "id": 21, "alt": 40.0},
        )
        for t in range(400)
    ]
    write_recording(path, "bare-mcap", TYPES, rows)
    return path


def test_remote_topics_recorded_under_their_bare_names_are_bound(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """carstopic1 and uastopic5 are no other platform's names: platform 2's and 3's data is
    read (it was "platform2/carstopic1 … is in no recording", and the verdict unknown)."""
    rec = bare_federation(tmp_path / "bare.mcap")
    code = main(
        [
            "monitor",
            "--json",
            "--config",
            str(FEDERATION),
            "--source",
            str(rec),
            "always (Speed[car2] > 60 -> eventually[0, 300] Speed[car2] <= 60)",
            "always (Altitude[uav2] > 30)",
        ]
    )
    out = capsys.readouterr()
    speeding, altitude = [json.loads(line) for line in out.out.splitlines()]
    assert code == 1
    assert "carstopic1" not in out.err and "uastopic5" not in out.err, out.err
    assert (speeding["verdict"], speeding["t"]) == (False, 300)
    assert altitude["verdict"] is True


def match(platform: str, topic: str) -> TopicMatch:
    return TopicMatch(platform, topic, "T", "msg.x", (), "X", ())


@pytest.mark.parametrize(
    ("m", "shared", "bare"),
    [
        (match("platform2", "carstopic1"), frozenset(), True),
        (match("platform2", "odom"), frozenset({"odom"}), False),  # another platform's too
        (match("platform1", "odom"), frozenset({"odom"}), True),  # the local platform's own
    ],
)
def test_a_bare_name_binds_unless_another_platforms_spec_uses_it(
    m: TopicMatch, shared: frozenset[str], bare: bool
) -> None:
    names = recording_names(m, "platform1", None, shared)
    assert names[:4] == [
        f"{m.platform}:/{m.topic}",
        f"{m.platform}:{m.topic}",
        f"/{m.platform}/{m.topic}",
        f"{m.platform}/{m.topic}",
    ]
    assert (f"/{m.topic}" in names and m.topic in names) is bare


def test_info_names_the_bare_topic_a_remote_spec_binds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = bare_federation(tmp_path / "bare.mcap")
    code, out = run(capsys, "info", "--config", str(FEDERATION), str(rec))
    assert code == 0
    assert "platform2/carstopic1 (AutomobileMsg) ← carstopic1" in out
    assert "platform3/uastopic5 (UasMsg) ← uastopic5" in out
    assert "platform2/carstopic2 (AutomobileMsg): in no recording" in out


def shared_pair(tmp_path: Path) -> Any:
    """Two robots without namespaces whose specs both name `odom`."""
    (tmp_path / "odom.sslt").write_text("topic odom:turtlesim/Pose contains X(me) = msg.x\n")
    ontology = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    config = tmp_path / "pair.toml"
    config.write_text(
        f'local = "robot1"\n[platforms.robot1]\nontology = "{ontology}"\nspecs = "odom.sslt"\n'
        f'[platforms.robot2]\nontology = "{ontology}"\nspecs = "odom.sslt"\n'
    )
    return config


def test_a_bare_name_two_platforms_use_is_the_local_platforms_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pose = (
        "float32 x\nfloat32 y\nfloat32 theta\nfloat32 linear_velocity\nfloat32 angular_velocity\n"
    )
    rec = tmp_path / "odom.mcap"
    write_recording(
        rec,
        "bare-mcap",
        {"turtlesim/msg/Pose": pose},
        [("/odom", "turtlesim/msg/Pose", 0, dict.fromkeys(pose.split()[1::2], 1.0))],
    )
    code, out = run(capsys, "info", "--config", str(shared_pair(tmp_path)), str(rec))
    assert code == 0
    assert "robot1/odom (turtlesim/Pose) ← /odom" in out
    assert "robot2/odom (turtlesim/Pose): in no recording" in out
