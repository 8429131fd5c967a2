"""Values over time (issue 30): terms over a feature's samples (prev, delta, rate, age), the
functions min, max, sqrt, hypot and abs, and the stream atoms observed and fresh; on
hand-written traces, then the checks engineers write first on small recordings made here."""

from __future__ import annotations

import json
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.live.loop import LiveSource
from dkreason.monitor import Monitor
from dkreason.parse.formula import parse_formula, unparse
from dkreason.progress import Progressor, Verdict
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.recording import write_recording
from dkreason.stream.terms import term_value

Trace = Sequence[tuple[Any, Any]]  # (time, X)


def judge(formula: str, trace: Trace) -> tuple[bool | None, Any]:
    """The verdict of `formula` over X's values, and when it was decided (None: at the end)."""
    p = Progressor()
    p.add(formula)
    for t, x in trace:
        for v in p.step(t, {"X": x}):
            return v.verdict, t
    (v,) = p.finish()
    return v.verdict, None


STEADY = [(0, 1), (1, 2), (2, 3), (4, 5)]  # rate 1/s throughout, a 2 s gap before the last


@pytest.mark.parametrize(
    ("formula", "trace", "want"),
    [
        # prev: the value at the previous sample (a state without a value is no sample)
        ("always (prev(X) < X)", STEADY, (None, None)),  # unknown at the first sample
        ("always (prev(X) == 2 -> X == 3)", [(0, 2), (1, None), (2, 3)], (None, None)),
        ("always (X > 1 -> prev(X) < X)", STEADY, (True, None)),
        ("always (X > 2 -> prev(X) == 2)", [(0, 2), (1, None), (2, 3), (3, 4)], (False, 3)),
        ("eventually (prev(X) == 1)", [(0, 1), (1, None), (2, 7)], (True, 2)),
        # delta and rate: per second of valid time between the two samples, exact
        ("always[1, 2] (delta(X) == 1)", STEADY, (True, 2)),
        ("always[1, oo] (rate(X) == 1)", STEADY, (True, None)),
        (
            "always (rate(X) < 1)",
            [(0, 0), (Fraction(1, 10), Fraction(1, 10))],
            (False, Fraction(1, 10)),
        ),
        ("always (rate(X) <= 1)", [(0, 0), (0.1, 0.1), (0.2, 0.3)], (False, 0.2)),
        # unknown before the second sample: never a violation
        ("always (rate(X) > 0)", [(0, 1)], (None, None)),
        # age: seconds since the last sample, on the stream clock
        ("always (age(X) < 2)", [(0, 1), (1, None), (2, None), (3, 4)], (False, 2)),
        ("always (age(X) <= 2)", [(0, 1), (1, None), (2, None), (3, 4)], (True, None)),
        # fresh: two-valued, false before the first sample
        ("always fresh(X, 1500ms)", [(0, 1), (1, None), (2, None)], (False, 2)),
        ("fresh(X, 1s)", [(0, None), (1, 1)], (False, 0)),
        ("always (observed(X) or not fresh(X, 1s))", [(0, 1), (1, None), (2, None)], (False, 1)),
        # functions: exact where the inputs are, unknown out of their domain
        ("always (max(X, 2) >= 2 and min(X, 2) <= 2)", STEADY, (True, None)),
        ("sqrt(X) == 3", [(0, 9)], (True, 0)),
        ("sqrt(X) == 1.5", [(0, Fraction(9, 4))], (True, 0)),
        ("hypot(X, 4) == 5", [(0, 3)], (True, 0)),
        ("always (sqrt(X) < 10)", [(0, -1)], (None, None)),
        ("always (sqrt(X - 1) < 10)", [(0, 1), (1, 0), (2, 101)], (False, 2)),
        ("always (abs(X) < 2)", [(0, -1), (1, -3)], (False, 1)),
        ("always (hypot(X, prev(X)) < 10)", [(0, None), (1, 6), (2, 8)], (False, 2)),
    ],
)
def test_terms_functions_and_atoms_on_hand_written_traces(
    formula: str, trace: Trace, want: tuple[bool | None, Any]
) -> None:
    assert judge(formula, trace) == want


def test_the_values_a_term_reads_are_shown_in_its_witness() -> None:
    p = Progressor()
    p.add("always (abs(rate(X)) < 1)")
    p.step(0, {"X": 0})
    (v,) = p.step(Fraction(1, 2), {"X": 1})
    assert v.witness == ("violated at 0.5: abs(rate(X)) < 1 was false at 0.5 (rate(X) = 2)")


@pytest.mark.parametrize(
    ("op", "want"),
    [("prev", 1.5), ("delta", 0.5), ("rate", 0.25), ("age", Fraction(1, 2))],
)
def test_a_term_is_read_from_the_last_two_samples_in_stream_units(op: str, want: Any) -> None:
    ns = Fraction(1, 10**9)
    assert term_value(op, 45 * 10**8, (4 * 10**9, 2.0), (2 * 10**9, 1.5), ns) == want


def test_a_term_without_its_samples_is_unknown() -> None:
    assert term_value("prev", 1, (0, 1.0), None, 1) is None
    assert term_value("age", 1, None, None, 1) is None
    assert term_value("rate", 1, (0, 1.0), (0, 0.5), 1) is None  # no time between them
    assert term_value("delta", 1, (1, "a"), (0, "b"), 1) is None


@pytest.mark.parametrize(
    "text",
    [
        "always rate(Yaw[r1]) < 1",
        "max(A, B) > sqrt(hypot(C, D)) + age(E)",
        "always fresh(GPS, 0.5s) and prev(X) != X",
        "forall r in Robot: always -delta(X[r]) >= min(1, 2)",
    ],
)
def test_terms_and_functions_print_as_written_and_parse_back(text: str) -> None:
    tree = parse_formula(text)
    assert unparse(tree) == text and parse_formula(unparse(tree)) == tree


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("rate(X)", "a number is not a formula"),
        ("max(X) > 1", "max takes 2 arguments, got 1"),
        ("fresh(X) ", r"fresh\(X, d\) needs a duration"),
        ("rate(1) > 2", "syntax error"),
    ],
)
def test_terms_and_functions_misused_are_one_line_errors(text: str, says: str) -> None:
    from dkreason.errors import ParseError

    with pytest.raises(ParseError, match=says):
        parse_formula(text)


# ---- on recordings: the checks engineers write first ----------------------------------------

ONTOLOGY = (
    """
@prefix : <http://r.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Robot a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
"""
    + "".join(
        f""":{name} a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
"""
        for name in ("Yaw", "PoseX", "CmdLin", "Fix")
    )
    + ":r1 a owl:NamedIndividual, :Robot .\n"
)
SPECS = """topic imu:Imu contains Yaw(r1) = msg.yaw
topic pose:Pose contains PoseX(r1) = msg.x
topic cmd_vel:Twist contains CmdLin(r1) = msg.linear
topic gps:NavSatFix contains Fix(r1) = msg.latitude
"""


@pytest.fixture
def robot(tmp_path: Path) -> Path:
    (tmp_path / "robot.ttl").write_text(ONTOLOGY)
    (tmp_path / "robot.sslt").write_text(SPECS)
    config = tmp_path / "robot.toml"
    config.write_text('[platforms.robot]\nontology = "robot.ttl"\nspecs = "robot.sslt"\n')
    return config


def recording(path: Path, rows: Sequence[tuple[str, float, dict[str, Any]]]) -> Path:
    """JSON lines from (topic, time s, message), in time order."""
    path.write_text(
        "".join(
            json.dumps({"topic": topic, "time": t, "msg": msg}) + "\n"
            for topic, t, msg in sorted(rows, key=lambda r: r[1])
        )
    )
    return path


def monitor_json(
    out: pytest.CaptureFixture[str], config: Path, source: Path, *args: str
) -> tuple[int, list[dict[str, Any]]]:
    code = main(["monitor", "--config", str(config), "--source", str(source), "--json", *args])
    return code, [json.loads(line) for line in out.readouterr().out.splitlines()]


MOVES = "always (CmdLin[r1] > 0.1 -> eventually[0, 1] prev(PoseX[r1]) != PoseX[r1])"


def turtle(moves_at: float | None) -> list[tuple[str, float, dict[str, Any]]]:
    """Pose at 10 Hz for 6 s, a velocity command of 0.5 m/s at 2 s; the pose changes from
    `moves_at` on (None: never)."""
    poses = [
        ("pose", n / 10, {"x": 0.5 * (n / 10 - moves_at) if moves_at and n / 10 > moves_at else 0})
        for n in range(61)
    ]
    return [*poses, ("cmd_vel", 0.05, {"linear": 0.0}), ("cmd_vel", 2.05, {"linear": 0.5})]


def test_whenever_cmd_vel_is_non_zero_the_pose_changes_within_1_s(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    moving = recording(tmp_path / "moving.jsonl", turtle(moves_at=2.3))
    code, (verdict,) = monitor_json(capsys, robot, moving, MOVES)
    assert (code, verdict["verdict"]) == (0, True)
    stuck = recording(tmp_path / "stuck.jsonl", turtle(moves_at=None))
    code, (verdict,) = monitor_json(capsys, robot, stuck, MOVES)
    assert (code, verdict["verdict"], verdict["t"]) == (1, False, 3.1)  # the window's end


def test_yaw_rate_stays_under_1_rad_per_s(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Yaw at 20 Hz turning 0.5 rad/s, then a jump of 0.2 rad in 50 ms at 3 s (4 rad/s)."""
    rows = [("imu", n / 20, {"yaw": 0.5 * n / 20 + (0.2 if n >= 60 else 0)}) for n in range(100)]
    code, (verdict,) = monitor_json(
        capsys, robot, recording(tmp_path / "yaw.jsonl", rows), "always (abs(rate(Yaw[r1])) < 1)"
    )
    assert (code, verdict["verdict"], verdict["t"]) == (1, False, 3)
    assert verdict["witness"].startswith(
        "violated at t+3 s: abs(rate(Yaw[r1])) < 1 was false at t+3 s (rate(Yaw[r1]) = 4.49"
    )


def test_the_gps_fix_is_never_older_than_2_s(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fix at 1 Hz, silent from 5 s to 9 s: with a maximum age of 2 s a state is made as
    the last fix grows too old, where it is (just) older than 2 s."""
    rows = [("gps", float(t), {"latitude": 48.0}) for t in (*range(6), 9, 10)]
    gps = recording(tmp_path / "gps.jsonl", rows)
    code, (verdict,) = monitor_json(
        capsys, robot, gps, "--max-age", "2", "always fresh(Fix[r1], 2s)"
    )
    assert (code, verdict["verdict"], verdict["t"]) == (1, False, 7.000000001)
    assert verdict["witness"] == (
        "violated at t+7.000000001 s: fresh(Fix[r1], 2s) was false at t+7.000000001 s "
        "(age(Fix[r1]) = 2.000000001)"
    )


@pytest.mark.parametrize("term", ["delta", "prev", "rate"])
def test_a_term_unknown_at_the_start_is_said_at_the_end_of_the_data(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], term: str
) -> None:
    """Judged from the start, a term over 1 Hz samples is unknown until its second sample:
    the undecided verdict says so (it once failed with a KeyError looking up the term)."""
    rows = [("imu", float(t), {"yaw": float(t)}) for t in range(1, 5)]
    code, (verdict,) = monitor_json(
        capsys,
        robot,
        recording(tmp_path / "yaw.jsonl", rows),
        "--start",
        "+0",
        f"always ({term}(Yaw[r1]) < 1000)",
    )
    assert (code, verdict["verdict"]) == (3, None)
    assert f"{term}(Yaw[r1]) unknown" in verdict["witness"]


def test_a_term_over_two_topics_sampled_at_once_keeps_its_earlier_sample(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Yaw from two IMUs stamped alike, 100 samples each: `delta` reads the newest sample of
    an earlier time however many share the newest time (old samples once went two at a time,
    which left `delta` with none before, unknown)."""
    specs = robot.parent / "robot.sslt"
    specs.write_text(specs.read_text() + "topic imu2:Imu contains Yaw(r1) = msg.yaw\n")
    rows = [(imu, n / 20, {"yaw": n / 100}) for n in range(100) for imu in ("imu", "imu2")]
    code, (verdict,) = monitor_json(
        capsys, robot, recording(tmp_path / "yaw.jsonl", rows), "always (delta(Yaw[r1]) < 1)"
    )
    assert (code, verdict["verdict"]) == (0, True)


STOPS = "always fresh(Fix[r1], 2s)"
TYPES = {"test_msgs/msg/Imu": "float64 yaw\n", "test_msgs/msg/NavSatFix": "float64 latitude\n"}


def stopped_fix(path: Path) -> Path:
    """A bag: the fix at 1 Hz from 0 to 5 s, silent until 9 s, then again at 9 and 10 s;
    yaw at 10 Hz throughout (the recording goes on without the fix)."""
    s = 10**9
    rows = [
        ("/gps", "test_msgs/msg/NavSatFix", t * s, {"latitude": 48.0}) for t in (*range(6), 9, 10)
    ]
    rows += [("/imu", "test_msgs/msg/Imu", n * s // 10, {"yaw": 0.0}) for n in range(101)]
    write_recording(path, "bare-mcap", TYPES, rows)
    return path


def test_fresh_is_a_deadline_its_verdict_comes_when_the_last_sample_grows_too_old(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No --max-age, and no sample of the fix between 5 and 9 s: `fresh(Fix[r1], 2s)` turns
    false 2 s after the last one (and 1 ns: the instant it is older), where a state is made
    for it, not at the next sample (fresh again) nor at the end."""
    bag = stopped_fix(tmp_path / "gps.mcap")
    code, (verdict,) = monitor_json(capsys, robot, bag, STOPS)
    assert (code, verdict["verdict"], verdict["t"]) == (1, False, 7.000000001)
    assert verdict["witness"] == (
        "violated at t+7.000000001 s: fresh(Fix[r1], 2s) was false at t+7.000000001 s "
        "(age(Fix[r1]) = 2.000000001)"
    )
    km = KnowledgeManager.from_config(robot)
    (found,) = [e for e in km.monitor(STOPS, bag) if isinstance(e, Verdict)]
    assert (found.verdict, found.t) == (False, 7.000000001)


@pytest.mark.parametrize(
    ("formula", "t"),
    [
        ("always (age(Fix[r1]) <= 2)", 7.000000001),
        ("always (age(Fix[r1]) < 2)", 7),
        ("always not (2 <= age(Fix[r1]))", 7),
        ("always (age(Fix[r1]) != 3)", 8),
    ],
)
def test_an_age_compared_with_a_constant_is_a_deadline_too(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], formula: str, t: float
) -> None:
    """The GPS fix never older than 2 s, as engineers write it: decided where the age
    crosses the bound (at 2 s, or just past it), not at the next sample, without --max-age."""
    code, (verdict,) = monitor_json(capsys, robot, stopped_fix(tmp_path / "gps.mcap"), formula)
    assert (code, verdict["verdict"], verdict["t"]) == (1, False, t)


def test_events_come_in_the_order_of_their_times(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A fix stamped 0.3 s before it is recorded, declaring at most 0.1 s: the deadline's
    verdict (its state made as the sample after the gap comes) is said before that sample's
    own delay violation, as their times are, not after it."""
    specs = robot.parent / "robot.sslt"
    specs.write_text(
        specs.read_text().replace("gps:NavSatFix", "gps:StampedFix [rate 1 Hz, delay 100ms]")
    )
    s = 10**9
    types = {**TYPES, "test_msgs/msg/StampedFix": "std_msgs/Header header\nfloat64 latitude\n"}
    rows = [
        ("/gps", "test_msgs/msg/StampedFix", t * s + 3 * s // 10, {"header": {"stamp": t}})
        for t in (*range(6), 9, 10)
    ]
    write_recording(tmp_path / "late.mcap", "bare-mcap", types, rows)
    code, events = monitor_json(capsys, robot, tmp_path / "late.mcap", "always (age(Fix[r1]) <= 2)")
    times = [e["time"] for e in events if "time" in e]
    assert times == sorted(times) and any(e.get("verdict") is False for e in events)


def test_a_late_sample_is_read_by_its_formulas_beside_others(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The fix stamped 0.3 s before it is recorded comes after the yaw's states past its
    time (late, said): the next state made reads it, and is its formula's own, so the fix's
    formula is violated beside the yaw's as it is alone (it stayed unknown there)."""
    specs = robot.parent / "robot.sslt"
    specs.write_text(specs.read_text().replace("gps:NavSatFix", "gps:StampedFix"))
    s = 10**9
    types = {**TYPES, "test_msgs/msg/StampedFix": "std_msgs/Header header\nfloat64 latitude\n"}
    rows: list[tuple[str, str, int, dict[str, Any]]] = [
        ("/gps", "test_msgs/msg/StampedFix", t * s + 3 * s // 10, {"header": {"stamp": t}})
        for t in range(1, 4)
    ]
    rows += [("/imu", "test_msgs/msg/Imu", n * s // 10, {"yaw": 0.0}) for n in range(41)]
    for n, row in enumerate(rows[:3]):
        row[3]["latitude"] = 48.0 + n
    write_recording(tmp_path / "late.mcap", "bare-mcap", types, rows)
    for formulas in (["always (Fix[r1] < 10)"], ["always (Fix[r1] < 10)", "always (Yaw[r1] < 1)"]):
        code, events = monitor_json(capsys, robot, tmp_path / "late.mcap", *formulas)
        (fix,) = [e for e in events if e.get("formula") == formulas[0]]
        assert fix["verdict"] is False and 1 <= fix["time"] < 1.5, formulas


def test_a_deadline_past_the_end_of_the_data_makes_no_state(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The fix stops at 5 s and the recording at 6 s: the deadline at 7 s is past the data,
    which never showed the fix older than 2 s."""
    s = 10**9
    rows = [("/gps", "test_msgs/msg/NavSatFix", t * s, {"latitude": 48.0}) for t in range(6)]
    rows += [("/imu", "test_msgs/msg/Imu", n * s // 10, {"yaw": 0.0}) for n in range(61)]
    write_recording(tmp_path / "short.mcap", "bare-mcap", TYPES, rows)
    code, (verdict,) = monitor_json(capsys, robot, tmp_path / "short.mcap", STOPS)
    assert (code, verdict["verdict"]) == (0, True)


def test_a_live_monitor_decides_at_the_deadline_as_time_passes(robot: Path) -> None:
    """Live, the fix's samples stop at 5 s: as the sources' clock passes 7 s (no sample of
    anything meanwhile), the state at the deadline is made and decides."""
    km = KnowledgeManager.from_config(robot)
    monitor = Monitor(km.plan(STOPS), km.request, StreamPolicy())
    processor = monitor.start(LiveSource())
    s = 10**9
    for t in range(6):
        processor.put("gps", t * s, t * s, (48.0,))
        processor.advance(t * s + s // 2)
    assert monitor.events() == []
    processor.advance(7 * s)
    assert monitor.events() == []
    processor.advance(7 * s + s // 2)
    (verdict,) = monitor.events()
    assert isinstance(verdict, Verdict)
    assert (verdict.verdict, verdict.t) == (False, 7.000000001)


def test_an_undefined_value_says_so_where_no_feature_was_unknown() -> None:
    p = Progressor()
    p.add("always (sqrt(X) >= 0)")
    p.step(0, {"X": -4})
    (v,) = p.finish()
    assert v.verdict is None and v.witness is not None
    assert v.witness.endswith(
        "a value it computes is undefined where it would be decided "
        "(the square root of a negative, a division by 0)"
    )


def test_a_witness_says_a_value_not_known_as_unknown() -> None:
    p = Progressor()
    p.add("always fresh(X, 1s)")
    (v,) = p.step(0, {"X": None})
    assert v.witness == "violated at 0: fresh(X, 1s) was false at 0 (age(X) = unknown)"


def test_a_state_file_leaving_a_feature_out_says_how_to_write_an_unknown() -> None:
    p = Progressor()
    p.add("always (Y < 5)")
    with pytest.raises(DkError, match=r'no value for Y \(write "Y": null for a value not known'):
        p.step(0, {"X": 1})


def test_orb_slam_publishes_within_5_s_from_the_api(robot: Path, tmp_path: Path) -> None:
    """Judged from the start of the recording: the pose's first message at 6.5 s is late,
    decided at the first state of its feature past the window."""
    rows = [("imu", t / 2, {"yaw": 0.0}) for t in range(20)] + [("pose", 6.5, {"x": 0.0})]
    km = KnowledgeManager.from_config(robot)
    run = km.monitor(
        "eventually[0, 5] fresh(PoseX[r1], 1s)",
        recording(tmp_path / "late.jsonl", rows),
        StreamPolicy(start_time="+0"),
    )
    (verdict,) = [e for e in run if hasattr(e, "verdict")]
    assert (verdict.verdict, verdict.t) == (False, 6.5)


def test_the_matcher_sees_the_feature_inside_a_term(robot: Path) -> None:
    km = KnowledgeManager.from_config(robot)
    request = km.check_formula("always (rate(Yaw[r1]) < 1 and fresh(Fix[r1], 2s))")
    topics = {str(f.feature.key): [t.topic for t in f.topics] for f in request.features}
    assert topics == {"Yaw[r1]": ["imu"], "Fix[r1]": ["gps"]}


def test_a_state_file_samples_each_feature_where_it_has_a_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    states = tmp_path / "states.jsonl"
    rows = [(0, 0.0), (1, None), (2, 1.0), (2.5, 3.0)]
    states.write_text("".join(json.dumps({"time": t, "values": {"X": x}}) + "\n" for t, x in rows))
    code = main(["progress", "--states", str(states), "--json", "always (rate(X) < 1)"])
    (verdict,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert (code, verdict["verdict"], verdict["time"]) == (1, False, 2.5)


# ---- no silent misreadings ----------------------------------------------------------------

MISREAD = "always (CmdLin[r1] > 0.1 -> eventually[0, 1] (previous (PoseX[r1]) != PoseX[r1]))"
WARNING = (
    "<formula>:1:57: PoseX[r1] != PoseX[r1] compares a term with itself (always false); its "
    "value at the previous sample is prev(PoseX[r1]) (previous applies to the whole "
    "comparison: `previous (X) != X` reads as `previous (X != X)`)"
)


def test_a_term_compared_with_itself_is_one_warning_from_the_api(robot: Path) -> None:
    km = KnowledgeManager.from_config(robot)
    assert km.plan(MISREAD).warnings == (WARNING,)
    assert km.check_formula(MISREAD).warnings[0] == WARNING
    assert km.check_formula("always (Yaw[r1] == Yaw[r1])").warnings[0] == (
        "<formula>:1:9: Yaw[r1] == Yaw[r1] compares a term with itself (always true); its value "
        "at the previous sample is prev(Yaw[r1])"
    )
    assert km.plan(MOVES).warnings == ()


@pytest.mark.parametrize(
    ("formula", "warned"),
    [
        ("always (age(Fix[r1]) <= 2)", False),
        ("always (2 >= age(Fix[r1]))", False),
        ("always fresh(Fix[r1], 2s)", False),
        ("always (age(Fix[r1]) - 2 <= 0)", True),
        ("always (abs(age(Fix[r1])) <= 2)", True),
        ("always (age(Fix[r1]) <= age(Yaw[r1]))", True),
    ],
)
def test_an_age_that_makes_no_deadline_is_one_warning(
    robot: Path, formula: str, warned: bool
) -> None:
    """Written so that the monitor can make no deadline of it, an age is read only at the
    states other samples make: a stopped sample is caught late, or not at all; it says so."""
    said = KnowledgeManager.from_config(robot).plan(formula).warnings
    assert any("makes no deadline" in w and "fresh(" in w for w in said) is warned


def test_a_term_compared_with_itself_is_a_warning_from_match_monitor_and_progress(
    robot: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["match", "--config", str(robot), MISREAD]) == 0
    assert f"Warning: {WARNING}" in capsys.readouterr().out.splitlines()
    stuck = recording(tmp_path / "stuck.jsonl", turtle(moves_at=None))
    code, (warning, verdict) = monitor_json(capsys, robot, stuck, MISREAD)
    assert warning == {"warning": WARNING} and verdict["verdict"] is False
    states = tmp_path / "states.jsonl"
    states.write_text('{"time": 0, "values": {"X": 1}}\n')
    assert main(["progress", "--states", str(states), "always (X != X)"]) == 1
    assert capsys.readouterr().err == (
        "warning: <formula>:1:9: X != X compares a term with itself (always false); its value "
        "at the previous sample is prev(X)\n"
    )
    main(["progress", "--states", str(states), "--json", "always (X != X)"])
    assert json.loads(capsys.readouterr().out.splitlines()[0])["warning"].startswith(
        "<formula>:1:9: X != X"
    )
