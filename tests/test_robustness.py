"""Robustness (issue 30): discrete-time STL space robustness of a formula over the states
judged, with its critical atom and where that atom's values came from; checked against
rtamt's discrete-time offline evaluator on random formulas and uniformly sampled traces."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.model import FeatureKey
from dkreason.parse.formula import parse_formula
from dkreason.progress import Progressor, Verdict
from dkreason.progress.kept import CHUNK, Kept
from dkreason.progress.robustness import margin, margins, robustness

SETTINGS = settings(
    max_examples=int(os.environ.get("DKREASON_EXAMPLES", "150")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)

# ---- the fragment both dkreason and rtamt read, in the spelling both accept ----------------

windows = st.one_of(
    st.just(""),
    st.tuples(st.integers(0, 2), st.integers(0, 3)).map(lambda p: f"[{p[0]},{p[0] + p[1]}]"),
)
comparisons = st.builds(
    lambda var, op, c: f"({var} {op} {c})",
    st.sampled_from(["x", "y"]),
    st.sampled_from(["<", "<=", ">", ">="]),
    st.integers(-3, 3),
)


@st.composite
def stl(draw: st.DrawFn, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(comparisons)
    kind = draw(st.sampled_from(["not", "unary", "unary", "binary", "binary"]))
    if kind == "not":
        return f"(not {draw(stl(depth - 1))})"
    if kind == "unary":
        op = draw(st.sampled_from(["always", "eventually", "historically", "once"]))
        return f"({op}{draw(windows)}{draw(stl(depth - 1))})"
    op = draw(st.sampled_from(["and", "or", "until", "since"]))
    window = draw(windows) if op in ("until", "since") else ""
    return f"({draw(stl(depth - 1))} {op}{window} {draw(stl(depth - 1))})"


signals = st.integers(2, 8).flatmap(  # rtamt 0.4 fails on one sample (UnboundLocalError)
    lambda n: st.tuples(
        st.lists(st.integers(-4, 4), min_size=n, max_size=n),
        st.lists(st.integers(-4, 4), min_size=n, max_size=n),
    )
)


def rtamt_margins(formula: str, xs: list[int], ys: list[int]) -> list[Any]:
    rtamt = pytest.importorskip("rtamt")
    spec = rtamt.StlDiscreteTimeOfflineSpecification()
    spec.declare_var("x", "float")
    spec.declare_var("y", "float")
    spec.spec = formula
    spec.parse()
    data = {"time": list(range(len(xs))), "x": [float(x) for x in xs], "y": [float(y) for y in ys]}
    return [v for _, v in spec.evaluate(data)]


@SETTINGS
@given(stl(), signals)
def test_margins_equal_rtamts_discrete_time_offline_evaluation(
    formula: str, signal: tuple[list[int], list[int]]
) -> None:
    xs, ys = signal
    trace = [
        (t, {FeatureKey("x"): x, FeatureKey("y"): y})
        for t, (x, y) in enumerate(zip(xs, ys, strict=True))
    ]
    ours = margins(parse_formula(formula), trace)
    theirs = rtamt_margins(formula, xs, ys)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs, strict=True):
        assert a == b or (math.isinf(a) and math.isinf(b) and (a > 0) == (b > 0)), (a, b)


# ---- per verdict and per instance, naming the critical atom and its source -----------------

ONTOLOGY = """
@prefix : <http://r.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Robot a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Yaw a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
:Heading a owl:Class ; owl:equivalentClass :Yaw ; rdfs:subClassOf [ a owl:Class ;
    owl:intersectionOf ( :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ;
    owl:allValuesFrom :Robot ] ) ] .
:r1 a owl:NamedIndividual, :Robot .
:r2 a owl:NamedIndividual, :Robot .
:bot1 a owl:NamedIndividual, :Robot ; owl:sameAs :r1 .
"""
SPECS = """topic imu1:Imu contains Heading(bot1) = msg.yaw
topic imu2:Imu contains Yaw(r2) = msg.yaw
"""


@pytest.fixture
def robots(tmp_path: Path) -> tuple[Path, Path]:
    """Two robots turning: r1 (read as Heading[bot1], bot1 = r1) reaches 2.5 rad at 5 s, r2
    stays at 1 rad; at 1 Hz."""
    (tmp_path / "r.ttl").write_text(ONTOLOGY)
    (tmp_path / "r.sslt").write_text(SPECS)
    config = tmp_path / "r.toml"
    config.write_text('[platforms.robot]\nontology = "r.ttl"\nspecs = "r.sslt"\n')
    rows = [("imu1", t, 0.5 * t) for t in range(6)] + [("imu2", t + 0.5, 1.0) for t in range(6)]
    source = tmp_path / "r.jsonl"
    source.write_text(
        "".join(
            json.dumps({"topic": topic, "time": t, "msg": {"yaw": y}}) + "\n"
            for topic, t, y in sorted(rows, key=lambda r: r[1])
        )
    )
    return config, source


def test_a_violation_says_by_how_much_at_which_atom_read_from_where(
    robots: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    config, source = robots
    argv = ["monitor", "--config", str(config), "--source", str(source), "--robustness"]
    assert main([*argv, "always (Yaw[r1] < 1.75)"]) == 1
    assert (
        "    robustness: violated by 0.25 at t+4 s: Yaw[r1] < 1.75 (Yaw[r1] = 2.0 read from "
        "robot/imu1 msg.yaw via Heading[bot1])"
    ) in capsys.readouterr().out.splitlines()


def test_each_instance_has_its_margin_and_the_formula_the_least(
    robots: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    config, source = robots
    code = main(
        [
            "monitor",
            "--config",
            str(config),
            "--source",
            str(source),
            "--robustness",
            "--json",
            "forall r in Robot: always (Yaw[r] < 3)",
        ]
    )
    (verdict,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert code == 0 and verdict["verdict"] is True
    # the sort names r1 as bot1 (its sameAs), as the quantifier's instances do
    assert verdict["robustness"] == {
        "value": 0.5,
        "atom": "Yaw[bot1] < 3",
        "time": 5,
        "t": 5,
        "values": {"Yaw[bot1]": 2.5},
        "sources": {"Yaw[bot1]": "robot/imu1 msg.yaw via Heading[bot1]"},
    }
    margins_ = {i["bindings"]["r"]: i["robustness"]["value"] for i in verdict["instances"]}
    assert margins_ == {"bot1": 0.5, "r2": 2.0}


def test_the_api_gives_the_margin_with_each_verdict(robots: tuple[Path, Path]) -> None:
    config, source = robots
    km = KnowledgeManager.from_config(config)
    run = km.monitor("eventually (Yaw[r2] > 0.5)", source, robustness=True)
    (verdict,) = [e for e in run if isinstance(e, Verdict)]
    assert verdict.robustness is not None
    assert (verdict.robustness.value, verdict.robustness.atom) == (0.5, "Yaw[r2] > 0.5")
    plain = km.monitor("eventually (Yaw[r2] > 0.5)", source)
    assert all(e.robustness is None for e in plain if isinstance(e, Verdict))


def test_unknown_values_give_no_margin_and_say_so() -> None:
    p = Progressor(robustness=True)
    p.add("always (X > 0)")
    p.step(0, {"X": 1})
    p.step(1, {"X": None})
    (v,) = p.finish()
    assert v.verdict is None and v.robustness is not None and v.robustness.value is None
    assert v.robustness.text() == "no margin: unknown values cover where it would be decided"
    p = Progressor(robustness=True)
    p.add("always (X > 0)")
    p.step(0, {"X": None})
    (v,) = p.step(1, {"X": -2})
    assert v.verdict is False and v.robustness is not None and v.robustness.value == -2


@pytest.mark.parametrize(
    ("formula", "said"),
    [
        ("always (hypot(X, Y) < 5)", "violated by 0 at 2: hypot(X, Y) < 5 (X = -4, Y = 3)"),
        ("always (X != -4)", "violated by 0 at 0: X != -4 (X = -4)"),
        ("always not (X <= -4)", "violated by 0 at 0: X <= -4 (X = -4)"),
        ("eventually (X >= -4)", "held by 0 at 0: X >= -4 (X = -4)"),
    ],
)
def test_a_formula_decided_by_nothing_has_a_margin_of_0_beside_unknown_values(
    formula: str, said: str
) -> None:
    """A comparison that fails (or holds) by exactly nothing decides a minimum (a maximum)
    whatever an unknown part is, as a negative (positive) margin does: 0, not 'no margin'."""
    p = Progressor(robustness=True)
    p.add(formula)
    verdicts = [
        *p.step(0, {"X": -4, "Y": None}),
        *p.step(1, {"X": 1, "Y": None}),
        *p.step(2, {"X": -4, "Y": 3}),
        *p.finish(),
    ]
    (v,) = verdicts
    assert v.robustness is not None and v.robustness.value == 0
    assert v.robustness.text() == said
    assert json.dumps(v.robustness.to_json()["value"]) == "0.0"


def test_progress_gives_the_margin_of_a_state_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text(
        "".join(json.dumps({"time": t, "values": {"X": x}}) + "\n" for t, x in enumerate([3, 2, 5]))
    )
    argv = ["progress", "--states", str(states), "--robustness"]
    assert main([*argv, "always (X >= 1)"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        "    robustness: held by 1 at 1: X >= 1 (X = 2)"
    )
    assert main([*argv, "--json", "eventually[0, 1] X > 4"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["robustness"]["value"] == -1 and out["robustness"]["atom"] == "X > 4"


# ---- kept states: memory bounded by the windows, the margin all states give ---------------

irregular = st.lists(
    st.tuples(
        st.sampled_from([1, 1, 2, 3]),
        st.one_of(st.none(), st.integers(-4, 4)),
        st.one_of(st.none(), st.integers(-4, 4)),
    ),
    min_size=1,
    max_size=40,
)
shapes = st.one_of(
    stl(),
    st.builds(lambda f: f"always {f}", stl(2)),
    st.builds(lambda f: f"eventually[1, oo] {f}", stl(2)),
    st.builds(lambda a, b: f"always ({a} -> eventually[0, 3] {b})", comparisons, comparisons),
    st.builds(lambda a, b: f"always {a} and not eventually {b}", stl(1), stl(1)),
)


def _trace(rows: list[tuple[int, Any, Any]]) -> list[tuple[int, dict[FeatureKey, Any]]]:
    out, t = [], 0
    for gap, x, y in rows:
        t += gap
        out.append((t, {FeatureKey("x"): x, FeatureKey("y"): y}))
    return out


@SETTINGS
@given(shapes, irregular, st.sampled_from([None, 0, 2]), st.integers(0, 4))
def test_the_states_kept_give_the_margin_every_state_gives(
    formula: str, rows: list[tuple[int, Any, Any]], beyond: int | None, before: int
) -> None:
    """Also for a formula added after a few states (another formula's: it reads none)."""
    everything = _trace(rows)
    trace = everything[before:] or everything[-1:]
    end = None if beyond is None else trace[-1][0] + beyond
    kept = Kept(chunk=3)  # folds every few states, as it does every few thousand
    kept.add("g", parse_formula("always historically (x > -9)"))
    for t, values in everything:
        if t == trace[0][0]:
            kept.add("f", parse_formula(formula))
        kept.append(t, values)
    assert margin(kept.margin("f", trace[-1][0], end)) == robustness(
        parse_formula(formula), trace, end
    )


fused_shapes = st.one_of(
    st.builds(lambda a: f"always {a}", comparisons),
    st.builds(lambda a, b: f"always ({a} and {b})", comparisons, comparisons),
    st.builds(lambda a, b: f"always ({a} -> eventually[0, 3] {b})", comparisons, comparisons),
    st.builds(lambda a: f"always not always[0, 2] {a}", comparisons),
)


@SETTINGS
@given(st.lists(fused_shapes, min_size=1, max_size=3), irregular, st.booleans())
def test_the_fast_step_keeps_what_the_general_engine_keeps(
    formulas: list[str], rows: list[tuple[int, Any, Any]], text: bool
) -> None:
    """Progressor.step with the fused fast step taking the states itself (and keeping them:
    folds every few states here), as text keys or feature keys: the verdicts, times and margins
    of the general engine, and the margin over the states judged."""
    trace = _trace(rows)
    seen = []
    for engine in ("auto", "general"):
        p = Progressor(engine=engine, robustness=True)
        assert p.kept is not None
        p.kept.chunk = p.kept.fold_at = 3
        for f in formulas:
            p.add(f)
        out = []
        for t, values in trace:
            given = {str(k): v for k, v in values.items()} if text else values
            out += [(v.verdict, v.time, v.robustness) for v in p.step(t, given)]
        out += [(v.verdict, v.time, v.robustness) for v in p.finish()]
        seen.append(out)
    assert seen[0] == seen[1]


@pytest.mark.parametrize(
    "formula",
    [
        "always (x > 0)",
        "always (x > 0 -> eventually[0, 5] y > 0)",
        "always not always[0, 5] (x > 0)",
        "eventually[0, 5] x > 3 and always historically[0, 2] y > -9",
    ],
)
def test_a_long_run_keeps_only_the_states_its_windows_need(formula: str) -> None:
    trace = [(t, {FeatureKey("x"): t % 7 - 1, FeatureKey("y"): t % 3}) for t in range(20_000)]
    kept = Kept(chunk=64)
    kept.add("f", parse_formula(formula))
    most = 0
    for t, values in trace:
        kept.append(t, values)
        most = max(most, len(kept.states))
    assert most <= 2 * 64 + 10
    assert margin(kept.margin("f", 19_999, None)) == robustness(parse_formula(formula), trace)


def test_the_progressor_keeps_no_state_for_a_decided_formula() -> None:
    p = Progressor(robustness=True)
    p.add("always (X > 0)")
    p.add("always (X > 5)")
    for t in range(10_000):
        verdicts = p.step(t, {"X": 1 + t % 3})
        assert not verdicts or t == 0
    assert len(p.kept.states) < 2 * CHUNK if p.kept is not None else False
    (v,) = p.finish()
    assert v.robustness is not None and v.robustness.value == 1


def test_a_response_that_fails_by_as_much_as_its_trigger_held_names_what_was_owed() -> None:
    """`P > 60 -> eventually[0, 2] P <= 60` with P at 70 throughout: trigger and target are
    both 10 from deciding, and the margin names the target, what never came."""
    p = Progressor(robustness=True)
    p.add("always (P > 60 -> eventually[0, 2] P <= 60)")
    verdicts = [v for t in range(5) for v in p.step(t, {"P": 70})] + p.finish()
    (v,) = verdicts
    assert v.verdict is False and v.robustness is not None
    assert (v.robustness.value, v.robustness.atom) == (-10, "P <= 60")
