"""Verdicts an engineer can act on (issue 28): quantified formulas judged per object, objects
that join while monitoring, no violation past the end of the data, startup and dropout, and
the same from the Python API as from the CLI; on small recordings made here."""

from __future__ import annotations

import json
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.judge import spans
from dkreason.live.loop import LiveSource
from dkreason.model import FeatureKey
from dkreason.monitor import Monitor
from dkreason.progress import UnknownSpan, Verdict
from dkreason.stream.policy import StreamPolicy

S = 10**9
ONTOLOGY = """
@prefix : <http://evo.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Estimator a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:PosZ a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ;
                     owl:allValuesFrom :Estimator ] ) ] .
:gt a owl:NamedIndividual, :Estimator .
:orb a owl:NamedIndividual, :Estimator .
:vins a owl:NamedIndividual, :Estimator .
:ghost a owl:NamedIndividual, :Estimator .
"""
# each estimator on its own topic; the ghost's is in no recording
SPECS = "".join(
    f"topic {e}:Odometry contains PosZ({e}) = msg.z\n" for e in ("gt", "orb", "vins", "ghost")
)
BOUNDED = "forall e in Estimator: always (abs(PosZ[e]) < 50)"


@pytest.fixture
def evo(tmp_path: Path) -> Path:
    """A config of four estimators, and its folder for recordings."""
    (tmp_path / "evo.ttl").write_text(ONTOLOGY)
    (tmp_path / "evo.sslt").write_text(SPECS)
    config = tmp_path / "evo.toml"
    config.write_text('[platforms.evo]\nontology = "evo.ttl"\nspecs = "evo.sslt"\n')
    return config


def recording(path: Path, rows: Sequence[tuple[str, float, float]]) -> Path:
    """JSON lines from (topic, time s, z), in time order."""
    path.write_text(
        "".join(
            json.dumps({"topic": topic, "time": t, "msg": {"z": z}}) + "\n"
            for topic, t, z in sorted(rows, key=lambda r: r[1])
        )
    )
    return path


def drift(seconds: int = 61) -> list[tuple[str, float, float]]:
    """At 1 Hz: ground truth climbs 1 m/s (50 m at 50 s), ORB-SLAM 2 m/s from 0.5 s (50 m at
    25.5 s), VINS sinks 1.5 m/s from 0.2 s (-50 m just after 33.2 s)."""
    return [
        row
        for t in range(seconds)
        for row in (("gt", t, float(t)), ("orb", t + 0.5, 2.0 * t), ("vins", t + 0.2, -1.5 * t))
    ]


Out = pytest.CaptureFixture[str]


def monitor_json(
    out: Out, config: Path, source: Path, *args: str
) -> tuple[int, list[dict[str, Any]]]:
    code = main(["monitor", "--config", str(config), "--source", str(source), "--json", *args])
    return code, [json.loads(line) for line in out.readouterr().out.splitlines()]


def statuses(verdict: dict[str, Any]) -> dict[str, str]:
    return {i["bindings"]["e"]: i["status"] for i in verdict["instances"]}


# ---- 1. quantifiers as per-object instances -------------------------------------------------


def test_one_silent_object_hides_no_violation_and_every_object_is_named(
    evo: Path,
    tmp_path: Path,
    capsys: Out,
) -> None:
    """Three estimators pass 50 m, the fourth never publishes: violated at the first (ORB-SLAM
    at 25.5 s), the others named as they follow, the fourth never observed."""
    code, lines = monitor_json(capsys, evo, recording(tmp_path / "evo.jsonl", drift()), BOUNDED)
    verdict, *updates = lines
    assert code == 1
    assert (verdict["verdict"], verdict["time"], verdict["at_end"]) == (False, 25.5, False)
    assert verdict["witness"] == (
        "e = orb violated at t+25.5 s: abs(PosZ[orb]) < 50 was false at t+25.5 s (PosZ[orb] = 50.0)"
    )
    assert statuses(verdict) == {"ghost": "open", "gt": "open", "orb": "violated", "vins": "open"}
    assert [u["update"] and u["verdict"] is False and u["time"] == 25.5 for u in updates] == [
        True
    ] * 3
    assert statuses(updates[-1]) == {
        "ghost": "never observed",
        "gt": "violated",
        "orb": "violated",
        "vins": "violated",
    }
    by = {i["bindings"]["e"]: i for i in updates[-1]["instances"]}
    assert (by["vins"]["time"], by["gt"]["time"]) == (34.2, 50)
    assert by["gt"]["witness"] == (
        "violated at t+50 s: abs(PosZ[gt]) < 50 was false at t+50 s (PosZ[gt] = 50.0)"
    )
    assert by["ghost"] == {
        "bindings": {"e": "ghost"},
        "verdict": None,
        "status": "never observed",
        "time": None,
        "witness": "no state had a value for every feature it reads (never seen: PosZ[ghost])",
    }
    assert by["gt"]["t"] == 50 and "t" not in by["ghost"]


def test_the_text_output_says_which_objects_violated_and_which_were_never_observed(
    evo: Path,
    tmp_path: Path,
    capsys: Out,
) -> None:
    source = recording(tmp_path / "evo.jsonl", drift())
    assert main(["monitor", "--config", str(evo), "--source", str(source), BOUNDED]) == 1
    out = capsys.readouterr().out
    assert "at 25.5 s: VIOLATED  " + BOUNDED in out
    assert "instances: violated e = orb; open e = ghost, e = gt, e = vins" in out
    assert "update (still VIOLATED): " + BOUNDED in out
    assert "instances: violated e = gt, e = orb, e = vins; never observed e = ghost" in out
    assert "e = vins violated at t+34.2 s: abs(PosZ[vins]) < 50 was false at t+34.2 s" in out
    assert out.count("│ " + BOUNDED) == 1  # the summary names the formula once


def test_an_instance_is_judged_from_its_own_first_value_and_holds_on_its_own(
    evo: Path,
    tmp_path: Path,
    capsys: Out,
) -> None:
    """`exists`: true once one instance holds; each instance from its own first sample."""
    rows = [("gt", t, 1.0) for t in range(10)] + [("orb", t + 5.5, 60.0) for t in range(5)]
    code, lines = monitor_json(
        capsys,
        evo,
        recording(tmp_path / "two.jsonl", rows),
        "exists e in Estimator: always (PosZ[e] < 50)",
    )
    (verdict,) = lines  # decided at the end, when every instance settled: no update follows
    assert code == 0 and verdict["verdict"] is True and verdict["at_end"] is True
    assert statuses(verdict) == {
        "ghost": "never observed",
        "gt": "held",
        "orb": "violated",
        "vins": "never observed",
    }


# ---- 2. objects that join while monitoring ---------------------------------------------------


def test_an_object_joining_while_monitoring_is_judged_from_its_arrival(evo: Path) -> None:
    """A fifth estimator joins the sort 10 s in: its instance starts then (the others go on as
    they were) and its violation is reported."""
    km = KnowledgeManager.from_config(evo)
    monitor = Monitor(km.plan(BOUNDED), km.request, StreamPolicy())
    source = LiveSource()
    processor = monitor.start(source)

    def feed(topic: str, t: float, z: float) -> None:
        processor.put(topic, int(t * S), int(t * S), (z,))
        processor.advance(int(t * S) + S // 2)

    for t in range(10):
        feed("gt", t, 1.0)
    assert monitor.events() == []
    km.kb.add_object("evo", "lio", "Estimator")
    km.add_topic("topic lio:Odometry contains PosZ(lio) = msg.z")
    assert monitor.extend(km.plan(BOUNDED)) == [(BOUNDED, "e = lio")]
    request = monitor.rematch(source)
    assert FeatureKey("PosZ", ("lio",)) in [f.feature.key for f in request.features]
    for t in range(10, 20):
        feed("gt", t, 1.0)
        feed("lio", t + 0.5, 10.0 * (t - 10))
    (verdict,) = monitor.events()
    assert isinstance(verdict, Verdict)
    assert (verdict.verdict, verdict.time) == (False, 15.5)
    assert verdict.witness == (
        "e = lio violated at t+15.5 s: abs(PosZ[lio]) < 50 was false at t+15.5 s (PosZ[lio] = 50.0)"
    )
    assert verdict.instances is not None
    assert [(i.name, i.status) for i in verdict.instances] == [
        ("e = ghost", "open"),
        ("e = gt", "open"),
        ("e = orb", "open"),
        ("e = vins", "open"),
        ("e = lio", "violated"),
    ]


# ---- 3. no deadline past the data ------------------------------------------------------------

TURTLE = """
@prefix : <http://turtles.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Robot a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Y a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
:turtle1 a owl:NamedIndividual, :Robot .
"""
RETURNS = "always (Y[turtle1] < 1 -> eventually[0, 5] (Y[turtle1] > 1))"


@pytest.fixture
def turtle(tmp_path: Path) -> tuple[Path, Path]:
    """turtlesim: Y above 1, until it drops below at 96.1 s; the recording ends at 100 s,
    3.9 s into the window in which it must come back."""
    (tmp_path / "t.ttl").write_text(TURTLE)
    (tmp_path / "t.sslt").write_text("topic pose:turtlesim/Pose contains Y(turtle1) = msg.y\n")
    config = tmp_path / "t.toml"
    config.write_text('[platforms.t]\nontology = "t.ttl"\nspecs = "t.sslt"\n')
    times = [t / 10 for t in range(0, 1001, 3)] + [96.1, 100.0]
    rows = [(t, 2.0 if t < 96.1 else 0.5) for t in sorted(set(times))]
    source = tmp_path / "pose.jsonl"
    source.write_text(
        "".join(json.dumps({"topic": "pose", "time": t, "msg": {"y": y}}) + "\n" for t, y in rows)
    )
    return config, source


def test_a_window_the_end_of_the_data_cuts_off_is_undecided(
    turtle: tuple[Path, Path], capsys: Out
) -> None:
    code, (verdict,) = monitor_json(capsys, *turtle, RETURNS)
    assert code == 3
    assert (verdict["verdict"], verdict["at_end"]) == (None, True)
    assert verdict["pending"] == (
        "eventually[0, 5] Y[turtle1] > 1: window [t+96.1, t+101.1] cut off at the end of the "
        "data, 3.9 s of 5 s seen"
    )


def test_finite_end_of_data_gives_the_finite_trace_verdict(
    turtle: tuple[Path, Path], capsys: Out
) -> None:
    code, (verdict,) = monitor_json(capsys, *turtle, "--end-of-data", "finite", RETURNS)
    assert code == 1
    assert (verdict["verdict"], verdict["at_end"]) == (False, True)
    assert verdict["witness"] == (
        "violated at t+100 s: Y[turtle1] < 1 held at t+96.1 s, but Y[turtle1] > 1 never held "
        "within [t+96.1, t+101.1]"
    )


def test_unbounded_operators_keep_their_finite_trace_values(
    turtle: tuple[Path, Path], capsys: Out
) -> None:
    code, lines = monitor_json(
        capsys, *turtle, "always (Y[turtle1] > 0)", "eventually (Y[turtle1] > 5)"
    )
    assert code == 1
    assert [(v["verdict"], v["at_end"]) for v in lines] == [(True, True), (False, True)]


# ---- 4. startup and dropout ------------------------------------------------------------------

PUBLISHES = "eventually[0, 5] observed(PosZ[orb]) and observed(PosZ[gt])"


def late_orb(tmp_path: Path) -> Path:
    """Ground truth from 0 s; ORB-SLAM's first pose 9.54 s later."""
    rows = [("gt", t, 0.0) for t in range(30)] + [("orb", t + 9.54, 0.0) for t in range(20)]
    return recording(tmp_path / "late.jsonl", rows)


def test_publishes_within_5_s_of_the_start_is_violated_when_judged_from_the_start(
    evo: Path,
    tmp_path: Path,
    capsys: Out,
) -> None:
    code, (verdict,) = monitor_json(capsys, evo, late_orb(tmp_path), "--start", "+0", PUBLISHES)
    assert code == 1 and (verdict["verdict"], verdict["time"]) == (False, 5)
    assert (
        verdict["witness"] == "violated at t+5 s: observed(PosZ[orb]) never held within [t+0, t+5]"
    )


def test_without_a_start_a_formula_is_judged_once_its_streams_exist(
    evo: Path,
    tmp_path: Path,
    capsys: Out,
) -> None:
    code, (verdict,) = monitor_json(capsys, evo, late_orb(tmp_path), PUBLISHES)
    assert code == 0 and (verdict["verdict"], verdict["time"]) == (True, 9.54)


def test_a_source_that_stops_is_said_silent_once(evo: Path, tmp_path: Path, capsys: Out) -> None:
    """ORB-SLAM stops at 20 s of a 60 s recording: unknown from when its last pose grew too
    old, said once with how long before the end it went silent."""
    rows = [("gt", t, 0.0) for t in range(61)] + [("orb", t, 0.0) for t in range(21)]
    code, (verdict,) = monitor_json(
        capsys, evo, recording(tmp_path / "stops.jsonl", rows), "always (abs(PosZ[orb]) < 50)"
    )
    assert code == 3 and verdict["verdict"] is None
    assert verdict["unknown"] == [{"feature": "PosZ[orb]", "from": 20, "to": 60, "silent": True}]
    assert verdict["witness"] == (
        "the data left it undecided: PosZ[orb] silent from t+20 s (40 s before the end)"
    )


def test_unknown_spans_closer_than_the_maximum_age_merge() -> None:
    x, y = FeatureKey("X"), FeatureKey("Y")
    unknown = [UnknownSpan(x, 3, 3), UnknownSpan(x, 5, 6), UnknownSpan(x, 20, 20)]
    unknown += [UnknownSpan(y, 7, 30)]
    said = spans(unknown, 30, 40, {x: 21, y: 6}.get, 5)
    assert said == [
        UnknownSpan(x, 3, 6),
        UnknownSpan(x, 20, 20),
        UnknownSpan(y, 6, 40, silent=True),
    ]


# ---- 9. the Python API gives what the CLI gives --------------------------------------------


@pytest.mark.parametrize(
    ("formula", "policy", "options"),
    [
        (BOUNDED, {}, []),
        (RETURNS, {}, []),
        (RETURNS, {"end_of_data": "finite"}, ["--end-of-data", "finite"]),
        (PUBLISHES, {"start_time": "+0"}, ["--start", "+0"]),
    ],
)
def test_the_api_gives_the_instances_pending_windows_and_times_of_the_cli(
    evo: Path,
    turtle: tuple[Path, Path],
    tmp_path: Path,
    formula: str,
    policy: dict[str, Any],
    options: list[str],
    capsys: Out,
) -> None:
    config, source = turtle if formula == RETURNS else (evo, tmp_path / "evo.jsonl")
    if formula != RETURNS:
        recording(source, drift() if formula == BOUNDED else [("gt", 0, 0.0), ("orb", 9.5, 0.0)])
    _, cli = monitor_json(capsys, config, source, *options, formula)
    run = KnowledgeManager.from_config(config).monitor(formula, source, StreamPolicy(**policy))
    assert [e.to_json() for e in run] == cli


def test_a_batch_row_names_the_instances_as_monitor_does(
    evo: Path, tmp_path: Path, capsys: Out
) -> None:
    from dkreason.batch import Job, Run, monitor_run, rows

    source = recording(tmp_path / "evo.jsonl", drift())
    _, (*_, final) = monitor_json(capsys, evo, source, BOUNDED)
    km = KnowledgeManager.from_config(evo)
    plan = km.plan(BOUNDED)
    job = Job(plan, km.request(plan), StreamPolicy(), ("evo",), (), "auto", (), None, None)
    (row,) = rows("b", Run("evo", (str(source),)), "d", monitor_run(job, Run("r", (str(source),))))
    assert row.verdict == "violated" and json.loads(str(row.instances)) == final["instances"]
    assert Fraction(row.t or 0) == Fraction(25.5)
