"""Real recordings as they come (issue 14): ROS topic names, namespaces, several recordings,
remapping, message types named with or without their package."""

from __future__ import annotations

import contextlib
import heapq
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dkreason.cli import main
from dkreason.stream.binding import _merged
from dkreason.stream.recording import Row, write_recording

from .conftest import REPO

TURTLES = REPO / "tests" / "data" / "turtles"
POSE = "float32 x\nfloat32 y\nfloat32 theta\nfloat32 linear_velocity\nfloat32 angular_velocity\n"
S = 10**9


def pose(x: float) -> dict[str, Any]:
    return {"x": x, "y": 0.0, "theta": 0.5, "linear_velocity": 0.0, "angular_velocity": 0.0}


def bag(path: Path, topics: dict[str, float], msgtype: str = "turtlesim/msg/Pose") -> Path:
    """Ten poses a second for a second on each topic, x starting at the value given."""
    rows: list[Row] = [
        (topic, msgtype, i * S // 10, pose(x + i)) for i in range(10) for topic, x in topics.items()
    ]
    write_recording(path, "bare-mcap", {msgtype: POSE}, rows)
    return path


def verdicts(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[Any], str]:
    code = main(["monitor", "--json", *argv])
    out = capsys.readouterr()
    lines = [json.loads(line) for line in out.out.splitlines()]
    return code, [(v["verdict"], v["time"]) for v in lines if "verdict" in v], out.err


def test_one_specs_file_serves_two_robots_through_their_namespaces(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = str(bag(tmp_path / "fleet.mcap", {"/robot1/pose": 1.0, "/robot2/pose": 20.0}))
    formula = "always (X[me] < 15)"
    assert verdicts(capsys, "--config", str(TURTLES / "robot1.toml"), "--source", rec, formula)[
        :2
    ] == (0, [(True, 0.9)])
    assert verdicts(capsys, "--config", str(TURTLES / "robot2.toml"), "--source", rec, formula)[
        :2
    ] == (1, [(False, 0)])


def pair(tmp_path: Path) -> Path:
    """Two robots without namespaces, each recording /odom."""
    (tmp_path / "odom.sslt").write_text("topic /odom:turtlesim/Pose contains X(me) = msg.x\n")
    config = tmp_path / "pair.toml"
    config.write_text(
        f'local = "robot1"\n[platforms.robot1]\nontology = "{TURTLES}/turtle.ttl"\n'
        f'specs = "odom.sslt"\n[platforms.robot2]\n'
        f'ontology = "{TURTLES}/turtle.ttl"\nspecs = "odom.sslt"\n'
    )
    return config


def test_several_recordings_bind_to_their_own_platform(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config = str(pair(tmp_path))
    one = bag(tmp_path / "one.mcap", {"/odom": 1.0})
    two = bag(tmp_path / "two.mcap", {"/odom": 20.0})
    formula = "always (X[me] < 15)"
    code, got, _ = verdicts(
        capsys,
        "--config",
        config,
        "--source",
        f"robot1={one}",
        "--source",
        f"robot2={two}",
        formula,
    )
    assert (code, got) == (0, [(True, 0.9)])  # robot2's /odom is not robot1's
    code, got, _ = verdicts(
        capsys,
        "--config",
        config,
        "--source",
        f"robot2={one}",
        "--source",
        f"robot1={two}",
        formula,
    )
    assert (code, got) == (1, [(False, 0)])
    code, _, err = verdicts(capsys, "--config", config, "--source", f"robot3={one}", formula)
    assert code == 2 and "'robot3' is not a platform of the config" in err


def test_merged_recordings_stream_in_record_time_order(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """X holds from the first recording until 0.45 s, then the second one's samples (later
    record times) take over: the merge interleaves them by record time."""
    config = str(pair(tmp_path))
    early = tmp_path / "early.mcap"
    late = tmp_path / "late.mcap"
    write_recording(
        early,
        "bare-mcap",
        {"turtlesim/msg/Pose": POSE},
        [("/odom", "turtlesim/msg/Pose", i * S // 10, pose(1.0)) for i in range(5)],
    )
    write_recording(
        late,
        "bare-mcap",
        {"turtlesim/msg/Pose": POSE},
        [("/odom", "turtlesim/msg/Pose", S // 20 + i * S // 10, pose(50.0)) for i in range(5)],
    )
    code, got, _ = verdicts(
        capsys,
        "--config",
        config,
        "--source",
        f"robot1={early}",
        "--source",
        f"robot1={late}",
        "always (X[me] < 15)",
    )
    assert (code, got) == (1, [(False, 0.05)])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(st.integers(0, 6), max_size=8).map(sorted), min_size=1, max_size=5))
def test_several_recordings_merge_as_heapq_merge_does(times: list[list[int]]) -> None:
    """By record time; on equal times the earlier recording's message first."""
    streams = [[(f"/r{r}", t, t, (n,)) for n, t in enumerate(ts)] for r, ts in enumerate(times)]
    assert list(_merged([iter(s) for s in streams])) == list(
        heapq.merge(*streams, key=lambda m: m[1])
    )


def test_remap_reads_a_recording_topic_under_another_name(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = str(bag(tmp_path / "sim.mcap", {"/turtle1/pose": 1.0}))
    args = ["--config", str(TURTLES / "robot1.toml"), "--source", rec, "always (X[me] < 15)"]
    assert verdicts(capsys, *args)[1] == [(None, None)]  # nothing is /robot1/pose
    assert verdicts(capsys, "--remap", "/turtle1/pose:=/robot1/pose", *args)[:2] == (
        0,
        [(True, 0.9)],
    )
    code, _, err = verdicts(capsys, "--remap", "nonsense", *args)
    assert code == 2 and "expected FROM:=TO" in err


@pytest.mark.parametrize(
    ("written", "fits"),
    [
        ("Pose", True),
        ("turtlesim/Pose", True),
        ("turtlesim/msg/Pose", True),
        ("geometry_msgs/Pose", False),
    ],
)
def test_a_message_type_may_be_written_with_or_without_its_package(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, written: str, fits: bool
) -> None:
    (tmp_path / "t.sslt").write_text(f"topic /turtle1/pose:{written} contains X(me) = msg.x\n")
    config = tmp_path / "t.toml"
    config.write_text(f'[platforms.t]\nontology = "{TURTLES}/turtle.ttl"\nspecs = "t.sslt"\n')
    rec = str(bag(tmp_path / "t.mcap", {"/turtle1/pose": 1.0}))
    code, got, err = verdicts(
        capsys, "--config", str(config), "--source", rec, "always (X[me] < 15)"
    )
    if fits:
        assert (code, got) == (0, [(True, 0.9)])
    else:
        assert (
            code == 2
            and "carries turtlesim/msg/Pose, but its specification says geometry_msgs/Pose" in err
        )


# ---- command-line conventions -----------------------------------------------------------------


def test_version_and_help_say_what_a_user_needs(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.startswith("dkreason ")
    with pytest.raises(SystemExit):
        main(["monitor", "--help"])
    text = capsys.readouterr().out
    assert "exit status: 0 every formula held, 1 one was violated" in text
    assert "default 5" in text and "example:" in text


def test_durations_take_the_formula_units(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = str(bag(tmp_path / "t.mcap", {"/robot1/pose": 1.0}))
    base = ["--config", str(TURTLES / "robot1.toml"), "--source", rec]
    assert verdicts(capsys, *base, "--max-age", "500ms", "--delay", "0.05s", "always (X[me] < 15)")[
        :2
    ] == (0, [(True, 0.9)])
    with pytest.raises(SystemExit) as done:
        verdicts(capsys, *base, "--max-age", "5 parsecs", "always (X[me] < 15)")
    err = capsys.readouterr().err
    assert done.value.code == 2 and "--max-age: '5 parsecs' is not a duration" in err


@pytest.mark.parametrize("suffix", [".png", ".svg", ".pdf"])
def test_the_plot_is_written_in_the_format_its_name_says(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, suffix: str
) -> None:
    rec = str(bag(tmp_path / "t.mcap", {"/robot1/pose": 1.0}))
    plot = tmp_path / f"x{suffix}"
    verdicts(
        capsys,
        "--config",
        str(TURTLES / "robot1.toml"),
        "--source",
        rec,
        "--plot",
        str(plot),
        "always (X[me] < 15)",
    )
    magic = {".png": b"\x89PNG", ".svg": b"<?xml", ".pdf": b"%PDF"}[suffix]
    assert plot.read_bytes().startswith(magic)
    code, _, err = verdicts(
        capsys,
        "--config",
        str(TURTLES / "robot1.toml"),
        "--source",
        rec,
        "--plot",
        str(tmp_path / "x.gif"),
        "always (X[me] < 15)",
    )
    assert code == 2 and "x.gif" in err and ".png, .svg or .pdf" in err


def test_a_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    import subprocess
    import sys

    rec = str(bag(tmp_path / "t.mcap", {"/robot1/pose": 1.0}))
    script = (
        f"{sys.executable} -m dkreason.cli monitor --json --config "
        f"{TURTLES / 'robot1.toml'} --source {rec} "
        + " ".join(f"'always (X[me] < {k})'" for k in range(20, 60))
        + " | head -1"
    )
    done = subprocess.run(
        ["bash", "-o", "pipefail", "-c", script], capture_output=True, text=True, timeout=120
    )
    assert done.stdout.count("\n") == 1 and "Traceback" not in done.stderr
    assert "BrokenPipe" not in done.stderr


def test_json_line_times_are_rounded_to_the_nanosecond(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rows = [{"topic": "/robot1/pose", "time": i * 0.1, "msg": pose(1.0 + i)} for i in range(10)]
    rec = tmp_path / "t.jsonl"
    rec.write_text("".join(json.dumps(r) + "\n" for r in rows))  # 0.30000000000000004 …
    assert verdicts(
        capsys,
        "--config",
        str(TURTLES / "robot1.toml"),
        "--source",
        str(rec),
        "always (X[me] < 15)",
    )[:2] == (0, [(True, 0.9)])


def test_a_push_source_that_fails_ends_the_monitor_with_the_error() -> None:
    import threading

    from dkreason import KnowledgeManager, StreamPolicy
    from dkreason.errors import DkError
    from dkreason.monitor import Monitor
    from dkreason.stream.sources import PushSource

    km = KnowledgeManager.from_config(TURTLES / "robot1.toml")
    source = PushSource()

    def feed() -> None:
        source.push("/robot1/pose", 0, pose(1.0))
        with contextlib.suppress(DkError):
            source.push("/robot1/pose", "soon", pose(2.0))  # not a time

    threading.Thread(target=feed).start()
    events = Monitor(km.plan(["always (X[me] < 15)"]), km.request, StreamPolicy()).run(source)
    with pytest.raises(DkError, match="must be a number"):
        list(events)


# ---- routing ---------------------------------------------------------------------------------


def test_a_topic_without_id_field_is_routed_once(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Each sample reaches its feature once: --unique sees no duplicate valid times, and a
    late sample is reported once."""
    rec = str(bag(tmp_path / "t.mcap", {"/robot1/pose": 1.0}))
    code = main(
        [
            "monitor",
            "--json",
            "--unique",
            "--config",
            str(TURTLES / "robot1.toml"),
            "--source",
            rec,
            "always (X[me] < 15)",
        ]
    )
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert code == 0 and not [e for e in lines if "violation" in e]


def test_a_string_id_is_routed_once(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    (tmp_path / "o.ttl").write_text(
        (TURTLES / "turtle.ttl")
        .read_text()
        .replace(
            ":me a owl:NamedIndividual, :Robot .", ':me a owl:NamedIndividual, :Robot ; :id "T-1" .'
        )
    )
    (tmp_path / "s.sslt").write_text(
        "topic /poses:turtlesim/Pose contains X(me) = msg.x for me = msg.name\n"
    )
    (tmp_path / "c.toml").write_text('[platforms.t]\nontology = "o.ttl"\nspecs = "s.sslt"\n')
    rows = [{"topic": "/poses", "time": t, "msg": {"name": "T-1", "x": 1.0}} for t in range(3)]
    rec = tmp_path / "s.jsonl"
    rec.write_text("".join(json.dumps(r) + "\n" for r in rows))
    code = main(
        [
            "monitor",
            "--json",
            "--unique",
            "--config",
            str(tmp_path / "c.toml"),
            "--source",
            str(rec),
            "always (X[me] < 15)",
        ]
    )
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert code == 0 and not [e for e in lines if "violation" in e], lines


# ---- message definitions ---------------------------------------------------------------------


def humble_bag(folder: Path) -> Path:
    """A rosbag2 sqlite3 folder as ROS 2 Humble writes it: no message definitions stored."""
    import re
    import sqlite3

    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    point = store.types["geometry_msgs/msg/Point"]
    with Writer(folder, version=8) as writer:
        conn = writer.add_connection("/robot1/point", "geometry_msgs/msg/Point", typestore=store)
        for i in range(10):
            writer.write(
                conn,
                i * S // 10,
                store.serialize_cdr(point(x=float(i), y=0.0, z=0.0), "geometry_msgs/msg/Point"),
            )
    db = sqlite3.connect(folder / f"{folder.name}.db3")
    db.execute("DROP TABLE message_definitions")
    db.execute("UPDATE schema SET schema_version = 3")
    db.commit()
    db.close()
    meta = folder / "metadata.yaml"
    meta.write_text(
        re.sub(r"\n +type_description_hash: *\n +\S+", "", meta.read_text()).replace(
            "  version: 8", "  version: 5"
        )
    )
    return folder


def test_a_bag_without_stored_definitions_is_read_with_the_standard_ones(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    (tmp_path / "p.sslt").write_text("topic point:geometry_msgs/Point contains X(me) = msg.x\n")
    config = tmp_path / "p.toml"
    config.write_text(
        f'[platforms.robot1]\nontology = "{TURTLES}/turtle.ttl"\n'
        f'specs = "p.sslt"\nnamespace = "/robot1"\n'
    )
    rec = str(humble_bag(tmp_path / "humble"))
    code, got, err = verdicts(
        capsys, "--config", str(config), "--source", rec, "always (X[me] < 15)"
    )
    assert (code, got) == (0, [(True, 0.9)])
    assert "stores no message definitions: using rosbags' ros2_humble ones" in err
    code, got, _ = verdicts(
        capsys,
        "--config",
        str(config),
        "--source",
        rec,
        "--typestore",
        "ros2_jazzy",
        "always (X[me] < 15)",
    )
    assert (code, got) == (0, [(True, 0.9)])


# ---- clocks ------------------------------------------------------------------------------------

STAMPED = "std_msgs/Header header\nfloat64 x\n"


def stamped_bag(path: Path, stamp0: float, record0: int, jitter: bool = False) -> Path:
    """Two stamped topics at 10 Hz for 3 s; header stamps start at stamp0 s, record times at
    record0 ns, each message recorded 20–36 ms after its stamp; with `jitter` the second
    topic's stamps run 30 ms behind the first's (ordinary sensor latency)."""
    rows: list[Row] = []
    for i in range(30):
        for topic, lag in (("/robot1/a", 0), ("/robot1/b", 30 if jitter else 0)):
            stamp = stamp0 + i / 10 - lag / 1000
            rows.append(
                (
                    topic,
                    "x/msg/Stamped",
                    record0 + i * S // 10 + 20_000_000 + i % 17 * 1_000_000,
                    {"header": {"stamp": stamp, "frame_id": ""}, "x": 1.0},
                )
            )
    write_recording(path, "bare-mcap", {"x/msg/Stamped": STAMPED}, rows)
    return path


def stamped_config(tmp_path: Path) -> Path:
    (tmp_path / "s.sslt").write_text(
        "topic a:x/Stamped contains X(me) = msg.x\ntopic b:x/Stamped contains Theta(me) = msg.x\n"
    )
    config = tmp_path / "s.toml"
    config.write_text(
        f'[platforms.robot1]\nontology = "{TURTLES}/turtle.ttl"\n'
        f'specs = "s.sslt"\nnamespace = "/robot1"\n'
    )
    return config


def test_a_sim_time_recording_is_judged_on_one_clock(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Header stamps near 928 s (a simulator's clock), record times near 1.78e9 s: no flood of
    late samples, decided verdicts, and one line saying which clock is used."""
    rec = stamped_bag(tmp_path / "sim.mcap", 928.0, 1_780_000_000 * S, jitter=True)
    code = main(
        [
            "monitor",
            "--json",
            "--config",
            str(stamped_config(tmp_path)),
            "--source",
            str(rec),
            "always (X[me] < 15 and Theta[me] < 15)",
        ]
    )
    out = capsys.readouterr()
    lines = [json.loads(line) for line in out.out.splitlines()]
    assert code == 0 and not [e for e in lines if "violation" in e]
    assert [e["verdict"] for e in lines if "verdict" in e] == [True]
    assert out.err.count("\n") == 1 and "header stamps" in out.err and "record time" in out.err


def test_ordinary_latency_is_not_late_by_default(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = stamped_bag(tmp_path / "real.mcap", 1_780_000_000.0, 1_780_000_000 * S, jitter=True)
    code = main(
        [
            "monitor",
            "--json",
            "--config",
            str(stamped_config(tmp_path)),
            "--source",
            str(rec),
            "always (X[me] < 15 and Theta[me] < 15)",
        ]
    )
    out = capsys.readouterr()
    lines = [json.loads(line) for line in out.out.splitlines()]
    assert code == 0 and not [e for e in lines if "violation" in e], lines[:3]
    assert out.err == ""  # stamps on the record clock: nothing to say


def test_epoch_times_are_decimals_never_fractions(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = stamped_bag(tmp_path / "real.mcap", 1_780_000_000.0, 1_780_000_000 * S)
    code = main(
        [
            "monitor",
            "--config",
            str(stamped_config(tmp_path)),
            "--source",
            str(rec),
            "always (X[me] > 5)",
        ]
    )
    out = capsys.readouterr().out
    assert code == 1 and "/" not in out.split("VIOLATED")[1].split("\n")[1]


# ---- what a recording holds ------------------------------------------------------------------


def test_info_lists_topics_clock_and_bindings(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    sim = stamped_bag(tmp_path / "sim.mcap", 928.0, 1_780_000_000 * S)
    config = stamped_config(tmp_path)
    with (tmp_path / "s.sslt").open("a") as specs:
        specs.write("topic gone:x/Stamped contains X(me) = msg.x\n")
    assert main(["info", "--config", str(config), str(sim)]) == 0
    out = capsys.readouterr().out
    assert "/robot1/a  x/msg/Stamped  30" in out and "another clock" in out
    assert (
        "robot1/a (x/Stamped) ← /robot1/a" in out
        and "robot1/gone (x/Stamped): in no recording" in out
    )
    assert main(["info", "--json", str(sim)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["recordings"][0]["clock"] == "record" and doc["specs"] == []
    assert {t["topic"]: t["count"] for t in doc["recordings"][0]["topics"]} == {
        "/robot1/a": 30,
        "/robot1/b": 30,
    }


def test_monitor_warns_about_relevant_topics_no_recording_holds(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = str(bag(tmp_path / "t.mcap", {"/robot1/pose": 1.0}))
    (tmp_path / "f.txt").write_text("# the fleet's formulas\nalways (X[me] < 15)\n\n")
    (tmp_path / "s.sslt").write_text(
        "topic pose:turtlesim/Pose contains X(me) = msg.x\n"
        "topic odom:turtlesim/Pose contains X(me) = msg.x\n"
    )
    config = tmp_path / "c.toml"
    config.write_text(
        f'[platforms.robot1]\nontology = "{TURTLES}/turtle.ttl"\n'
        f'specs = "s.sslt"\nnamespace = "/robot1"\n'
    )
    code, got, err = verdicts(
        capsys, "--config", str(config), "--source", rec, "-f", str(tmp_path / "f.txt")
    )
    assert (code, got) == (0, [(True, 0.9)])
    assert err == "warning: robot1/odom (for X[me]) is in no recording\n"


# ---- typed atoms -------------------------------------------------------------------------------

TYPED = "std_msgs/Header header\nstring mode\nbool armed\nfloat64 alt\nfloat64[3] pos\n"


def typed_setup(tmp_path: Path) -> list[str]:
    (tmp_path / "o.ttl").write_text(
        (TURTLES / "turtle.ttl").read_text()
        + "".join(
            f":{n} a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( "
            f":UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom "
            f":Robot ] ) ] .\n"
            for n in ("Mode", "Armed", "Alt", "Pos", "Frame")
        )
    )
    (tmp_path / "s.sslt").write_text(
        "topic state:x/State contains Mode(me) = msg.mode, Armed(me) = msg.armed, "
        "Alt(me) = msg.alt, Pos(me) = msg.pos, Frame(me) = msg.header.frame_id\n"
    )
    (tmp_path / "c.toml").write_text(
        '[platforms.robot1]\nontology = "o.ttl"\nspecs = "s.sslt"\nnamespace = "/robot1"\n'
    )
    rows: list[Row] = [
        (
            "/robot1/state",
            "x/msg/State",
            i * S // 10,
            {
                "header": {"stamp": i / 10, "frame_id": "odom"},
                "mode": "AUTO" if i < 8 else "MANUAL",
                "armed": True,
                "alt": -2.0 + i,
                "pos": np.zeros(3),
            },
        )
        for i in range(10)
    ]
    write_recording(tmp_path / "r.mcap", "bare-mcap", {"x/msg/State": TYPED}, rows)
    return ["--config", str(tmp_path / "c.toml"), "--source", str(tmp_path / "r.mcap")]


def test_strings_booleans_and_abs_are_typed_atoms(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    args = typed_setup(tmp_path)
    assert verdicts(capsys, *args, 'always (Frame[me] == "odom" and Armed[me])')[:2] == (
        0,
        [(True, 0.9)],
    )
    assert verdicts(capsys, *args, 'always (Mode[me] != "MANUAL")')[:2] == (1, [(False, 0.8)])
    assert verdicts(capsys, *args, "always (abs(Alt[me]) <= 7 and -Alt[me] < 3)")[:2] == (
        0,
        [(True, 0.9)],
    )


@pytest.mark.parametrize(
    ("formula", "says"),
    [
        (
            "always (Mode[me] > 3)",
            "Mode[me] is read from /robot1/state msg.mode, a string, but "
            "the formula uses it as a number",
        ),
        (
            'always (Alt[me] == "high")',
            "Alt[me] is read from /robot1/state msg.alt, a float64, "
            "but the formula uses it as a string",
        ),
        ("always (Pos[me] > 0)", "Pos[me] is read from /robot1/state msg.pos, an array, but"),
        ("always Alt[me]", "a float64, but the formula uses it as a condition"),
        ('always (Mode[me] < "B")', "strings compare only with == or !=, not <"),
    ],
)
def test_type_errors_are_one_line_before_any_message(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, formula: str, says: str
) -> None:
    code, got, err = verdicts(capsys, *typed_setup(tmp_path), formula)
    assert code == 2 and got == [] and err.count("\n") == 1 and says in err, err


def test_a_wrong_embedded_definition_is_refused_not_decoded_into_garbage(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """The bag says x/msg/T is `uint8 level` but its messages hold two float64s (rosbag2's
    own `talker` test bag has such a mismatch): one line, never values read at wrong offsets."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    right, wrong = get_typestore(Stores.EMPTY), get_typestore(Stores.EMPTY)
    right.register(get_types_from_msg("float64 a\nfloat64 b\n", "x/msg/T"))
    wrong.register(get_types_from_msg("uint8 level\n", "x/msg/T"))
    folder = tmp_path / "talker"
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/robot1/level", "x/msg/T", typestore=wrong)
        for i in range(5):
            writer.write(
                conn,
                i * S,
                right.serialize_cdr(right.types["x/msg/T"](a=float(i), b=2.0), "x/msg/T"),
            )
    (tmp_path / "l.sslt").write_text("topic level:x/T contains X(me) = msg.level\n")
    config = tmp_path / "l.toml"
    config.write_text(
        f'[platforms.robot1]\nontology = "{TURTLES}/turtle.ttl"\n'
        f'specs = "l.sslt"\nnamespace = "/robot1"\n'
    )
    code, got, err = verdicts(
        capsys, "--config", str(config), "--source", str(folder), "always (X[me] < 100)"
    )
    assert code == 2 and got == [] and err.count("\n") == 1
    assert "/robot1/level: its messages do not match the definition of x/msg/T" in err

    # --msg gives the right definition, and it overrides the embedded one
    (tmp_path / "x" / "msg").mkdir(parents=True)
    (tmp_path / "x" / "msg" / "T.msg").write_text("float64 a\nfloat64 b\n")
    (tmp_path / "l.sslt").write_text("topic level:x/T contains X(me) = msg.a\n")
    code, got, err = verdicts(
        capsys,
        "--config",
        str(config),
        "--source",
        str(folder),
        "--msg",
        str(tmp_path / "x" / "msg" / "T.msg"),
        "always (X[me] < 4)",
        "always (X[me] < 5)",
    )
    assert code == 1 and sorted(v for v, _ in got) == [False, True], err
    assert "x/msg/T: the definition of --msg" in err  # said once, on stderr


def test_times_on_an_epoch_clock_read_relative_and_as_dates(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec = stamped_bag(tmp_path / "real.mcap", 1_780_000_000.0, 1_780_000_000 * S)
    args = [
        "--config",
        str(stamped_config(tmp_path)),
        "--source",
        str(rec),
        "always (X[me] < 15 and eventually[0, 0.25] Theta[me] > 5)",
    ]
    assert main(["monitor", "--json", *args]) == 1
    (verdict,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    # t from the recording's start, its first record (20 ms after the first stamp), to the
    # stamp written as the float 1780000000.3 (1780000000.299999952 s)
    assert verdict["time"] == 1780000000.3 and verdict["t"] == 0.279999952
    assert main(["monitor", *args]) == 1
    assert "at t+0.279999952 s (2026-05-28T20:26:40.300Z): VIOLATED" in capsys.readouterr().out


def test_start_and_end_may_count_from_the_recordings_start(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """On an epoch clock `--start 50` would drop everything; `+0.25` means 0.25 s after the
    recording's start (its first record, 20 ms after the first stamp), where the formula is
    judged from: X, sampled at 10 Hz, has no value there yet."""
    rec = stamped_bag(tmp_path / "real.mcap", 1_780_000_000.0, 1_780_000_000 * S)
    args = [
        "--config",
        str(stamped_config(tmp_path)),
        "--source",
        str(rec),
        "--json",
        "always (observed(X[me]) -> X[me] > 0)",
    ]
    assert main(["monitor", "--start", "+0.25", "--end", "+1", *args]) == 0
    (verdict,) = [
        json.loads(line) for line in capsys.readouterr().out.splitlines() if '"verdict"' in line
    ]
    assert verdict["time"] == 1780000001 and verdict["t"] == 0.98
    assert main(["monitor", "--start", "+0.25", "--end", "2", *args]) == 2
    assert "both relative (+SECONDS) or both absolute" in capsys.readouterr().err


def test_an_mcap_with_json_channels_beside_its_ros_ones_is_read_whole(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Foxglove and dkreason's own --record write JSON channels into ROS 2 MCAP files; rosbags
    stops at their schema encoding.  The ROS channels are read as usual (not as damage) and the
    others skipped, with a note."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    plain = bag(tmp_path / "plain.mcap", {"/robot1/pose": 1.0})
    mixed = tmp_path / "mixed.mcap"
    with plain.open("rb") as f, mixed.open("wb") as out:
        writer = Writer(out)
        writer.start(profile="ros2", library="test")
        reader = make_reader(f)
        ids: dict[int, int] = {}
        summary = reader.get_summary()
        assert summary is not None
        for schema in summary.schemas.values():
            ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
        chans = {
            c.id: writer.register_channel(c.topic, c.message_encoding, ids[c.schema_id])
            for c in summary.channels.values()
        }
        notes = writer.register_channel(
            "/notes", "json", writer.register_schema("Note", "jsonschema", b'{"type": "object"}')
        )
        for _, channel, message in reader.iter_messages():
            writer.add_message(
                chans[channel.id], message.log_time, message.data, message.publish_time
            )
            writer.add_message(notes, message.log_time, b'{"note": 1}', message.log_time)
        writer.finish()  # type: ignore[no-untyped-call]
    code, found, err = verdicts(
        capsys,
        "--config",
        str(TURTLES / "robot1.toml"),
        "--source",
        str(mixed),
        "always (X[me] < 15)",
    )
    assert (code, found) == (0, [(True, 0.9)])
    assert "damaged" not in err and "sequentially" not in err
    assert "/notes (json)" in err
