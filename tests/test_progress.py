"""The progression engine against a simple offline evaluator of the semantics (tests/oracle.py),
and its two engines (the fused monitors and the general graph) against each other.

Random formulas (every operator, nested, bounded and unbounded intervals, [a, a]) on random
traces with uneven steps that do not start at 0, with unknown values.
"""

from __future__ import annotations

import os
from fractions import Fraction
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason.errors import DkError
from dkreason.model import FeatureKey
from dkreason.parse.formula import feature_key as parse_key
from dkreason.parse.formula import parse_formula
from dkreason.progress import Progressor

from .oracle import Trace, holds

# DKREASON_EXAMPLES=20000 for a long run; the default keeps the suite quick
SETTINGS = settings(
    max_examples=int(os.environ.get("DKREASON_EXAMPLES", "400")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)

intervals = st.one_of(
    st.just(""),
    st.tuples(st.integers(0, 3), st.integers(0, 4)).map(lambda p: f"[{p[0]}, {p[0] + p[1]}]"),
    st.integers(0, 3).map(lambda a: f"[{a}, oo]"),
    st.integers(0, 3).map(lambda a: f"[{a}, {a}]"),
)
atoms = st.sampled_from(
    [
        "P",
        "Q",
        "X > 2",
        "X <= 1",
        "true",
        "false",
        "X + 1 >= 3",
        "rate(X) > 1",
        "delta(X) < 0",
        "prev(X) == 2",
        "age(X) <= 1",
        "fresh(X, 1500ms)",
        "max(X, prev(X)) >= 3",
        "sqrt(X - 1) < 1.5",
        "min(hypot(X, 1), 2) < 2",
    ]
)
UNARY = ["not", "always", "eventually", "next", "historically", "once", "previous"]
BINARY = ["and", "or", "->", "<->", "until", "since"]


@st.composite
def formulas(draw: st.DrawFn, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(atoms)
    if draw(st.booleans()):
        op = draw(st.sampled_from(UNARY))
        sub = draw(formulas(depth - 1))
        return f"not ({sub})" if op == "not" else f"{op}{draw(intervals)} ({sub})"
    op = draw(st.sampled_from(BINARY))
    left, right = draw(formulas(depth - 1)), draw(formulas(depth - 1))
    interval = draw(intervals) if op in ("until", "since") else ""
    return f"({left}) {op}{interval} ({right})"


@st.composite
def traces(draw: st.DrawFn) -> Trace:
    n = draw(st.integers(1, 7))
    t = Fraction(draw(st.sampled_from([0, 1, 5])))
    out: Trace = []
    for _ in range(n):
        values = {
            "P": draw(st.sampled_from([True, False, True, False, None])),
            "Q": draw(st.sampled_from([True, False, False, None])),
            "X": draw(st.sampled_from([0, 1, 2, 3, 4, None])),
        }
        out.append((t, values))
        t += draw(
            st.sampled_from([Fraction(1), Fraction(1), Fraction(2), Fraction(3), Fraction(1, 2)])
        )
    return out


def run(formula: str, trace: Trace, end_of_data: str = "open") -> tuple[bool | None, int | None]:
    """(verdict, index of the deciding state or None if settled by finish)."""
    p = Progressor(end_of_data=end_of_data)
    p.add(formula)
    for k, (t, values) in enumerate(trace):
        for v in p.step(t, values):
            assert not v.at_end
            return v.verdict, k
    (v,) = p.finish()
    assert v.at_end
    return v.verdict, None


@SETTINGS
@given(formulas(), traces())
def test_verdicts_equal_the_offline_semantics(formula: str, trace: Trace) -> None:
    verdict, _ = run(formula, trace)
    assert verdict == holds(parse_formula(formula), trace, 0)


@SETTINGS
@given(formulas(), traces())
def test_finite_end_of_data_verdicts_equal_the_finite_trace_semantics(
    formula: str, trace: Trace
) -> None:
    verdict, _ = run(formula, trace, "finite")
    assert verdict == holds(parse_formula(formula), trace, 0, finite=True)


@SETTINGS
@given(formulas(), traces())
def test_an_early_verdict_is_final_and_holds_on_the_stream_cut_right_after_it(
    formula: str, trace: Trace
) -> None:
    verdict, k = run(formula, trace)
    if k is not None:
        f = parse_formula(formula)
        assert verdict is not None
        assert verdict == holds(f, trace, 0) == holds(f, trace[: k + 1], 0)


@SETTINGS
@given(formulas(), traces())
def test_verdicts_come_no_later_than_a_three_valued_evaluation_of_the_prefix(
    formula: str, trace: Trace
) -> None:
    f = parse_formula(formula)
    _, k = run(formula, trace)
    forced = next(
        (n for n in range(len(trace)) if holds(f, trace[: n + 1], 0, prefix=True) is not None), None
    )
    if forced is not None:
        assert k is not None and k <= forced


single = st.one_of(
    st.tuples(
        st.sampled_from(["always", "eventually", "next", "historically", "once", "previous"]),
        intervals,
        atoms,
    ).map(lambda p: f"{p[0]}{p[1]} ({p[2]})"),
    st.tuples(atoms, st.sampled_from(["until", "since"]), intervals, atoms).map(
        lambda p: f"({p[0]}) {p[1]}{p[2]} ({p[3]})"
    ),
    st.tuples(atoms, intervals, atoms).map(
        lambda p: f"always (({p[0]}) -> eventually{p[1]} ({p[2]}))"
    ),
    st.tuples(atoms, intervals, atoms).map(
        lambda p: f"always (not ({p[0]}) or eventually{p[1]} ({p[2]}))"
    ),
    st.tuples(intervals, atoms).map(lambda p: f"always not (always{p[0]} ({p[1]}))"),
    st.tuples(atoms, atoms).map(lambda p: f"always (({p[0]}) and not ({p[1]}))"),
)


@SETTINGS
@given(single, traces())
def test_single_operators_and_response_formulas_decide_exactly_at_the_forcing_state(
    formula: str, trace: Trace
) -> None:
    f = parse_formula(formula)
    _, k = run(formula, trace)
    forced = next(
        (n for n in range(len(trace)) if holds(f, trace[: n + 1], 0, prefix=True) is not None), None
    )
    assert k == forced


def test_response_formula_decides_at_the_state_that_closes_the_window() -> None:
    p = Progressor()
    p.add("always (Speed[car1] > 60 -> eventually[0, 300] Speed[car1] <= 60)")
    decided = []
    for t in range(0, 1000, 50):
        decided += [(t, v) for v in p.step(t, {"Speed[car1]": 70 if t >= 100 else 50})]
    ((t, verdict),) = decided
    assert t == 400 and verdict.verdict is False
    assert "Speed[car1] <= 60 never held within [100, 400]" in str(verdict.witness)


END = ("eventually Q", "next P", "always P", "P until Q", "always[0, 100] P", "eventually[0, 5] Q")


def test_at_the_end_of_the_data_a_cut_window_is_undecided_and_unbounded_operators_close() -> None:
    p = Progressor()
    for f in END:
        p.add(f)
    assert p.step(0, {"P": True, "Q": False}) == []
    got = {v.formula: (v.verdict, v.at_end, v.pending) for v in p.finish(Fraction(39, 10))}
    assert got == {
        "eventually Q": (False, True, None),
        "next P": (False, True, None),
        "always P": (True, True, None),
        "P until Q": (False, True, None),
        "always[0, 100] P": (
            None,
            True,
            "always[0, 100] P: window [0, 100] cut off at the end of the data, 3.9 s of 100 s seen",
        ),
        "eventually[0, 5] Q": (
            None,
            True,
            "eventually[0, 5] Q: window [0, 5] cut off at the end of the data, 3.9 s of 5 s seen",
        ),
    }


def test_finite_end_of_data_closes_every_window_at_the_last_state() -> None:
    p = Progressor(end_of_data="finite")
    for f in END:
        p.add(f)
    assert p.step(0, {"P": True, "Q": False}) == []
    got = {v.formula: (v.verdict, v.at_end) for v in p.finish(Fraction(39, 10))}
    assert got == {
        "eventually Q": (False, True),
        "next P": (False, True),
        "always P": (True, True),
        "P until Q": (False, True),
        "always[0, 100] P": (True, True),
        "eventually[0, 5] Q": (False, True),
    }


def test_a_window_the_data_passed_closes_even_without_a_state_in_it() -> None:
    """The end of the data may come after the last state (the recording went on without
    sampling these features): a window it passed is decided."""
    p = Progressor()
    p.add("eventually[0, 5] Q")
    p.add("eventually[0, 50] Q")
    assert p.step(0, {"Q": False}) == []
    got = {v.formula: (v.verdict, v.at_end) for v in p.finish(end=10)}
    assert got == {"eventually[0, 5] Q": (False, True), "eventually[0, 50] Q": (None, True)}


def test_times_and_units_are_exact() -> None:
    p = Progressor()
    p.add("eventually[0.3, 0.3] P")
    p.add("always[0ms, 250ms] Q")
    for t, values in (
        (0.1, {"P": False, "Q": True}),
        (0.2, {"P": False, "Q": True}),
        (0.35, {"P": False, "Q": True}),
        (0.4, {"P": True, "Q": False}),
    ):
        for v in p.step(t, values):
            assert (v.formula, v.verdict, v.time) in {
                ("always[0ms, 250ms] Q", True, 0.35),
                ("eventually[0.3, 0.3] P", True, 0.4),
            }
    assert p.finish() == []


def test_unknown_values_are_reported_with_their_spans_and_never_as_a_violation() -> None:
    p = Progressor()
    p.add("always (Speed[car2] > 60 -> eventually[0, 300] Speed[car2] <= 60)")
    for t in range(0, 600, 100):
        assert p.step(t, {"Speed[car2]": 70 if t < 200 else None}) == []
    (v,) = p.finish()
    assert v.verdict is None and v.at_end
    assert [(str(u.feature), u.start, u.end) for u in v.unknown] == [("Speed[car2]", 200, 500)]


def test_feature_keys_ignore_whitespace() -> None:
    p = Progressor()
    p.add("always Close[uav1,uav2]")
    assert p.step(0, {"Close[uav1, uav2]": False})[0].verdict is False


def test_text_keys_are_read_once_per_spelling_not_once_a_state(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import dkreason.progress.progressor as progressor

    read: list[str] = []

    def counted(text: str) -> FeatureKey | None:
        read.append(text)
        return parse_key(text)

    monkeypatch.setattr(progressor, "feature_key", counted)
    p = Progressor()
    p.add("always (X[a] > 1 and Y < 5)")
    for t in range(100):
        assert not p.step(t, {"X[a]": 2, "Y": 3, "unused": 0})
    assert sorted(read) == ["X[a]", "Y", "unused"]
    mixed: dict[Any, int] = {FeatureKey("X", ("a",)): 2, "Y": 3}  # spelled another way
    assert not p.step(100, mixed)
    (v,) = p.step(101, {"X[ a ]": 2, "Y": 9})
    assert v.verdict is False


@pytest.mark.parametrize(
    ("steps", "says"),
    [
        ([(0, {"P": True}), (0, {"P": True})], "time 0 is not after the previous state's time 0"),
        ([(0, {"Q": True})], "the state at time 0 has no value for P"),
        ([(0, {"P": 3})], "P is used as a condition but has the value 3 at time 0"),
    ],
)
def test_bad_states_are_errors_naming_feature_and_time(steps: list[Any], says: str) -> None:
    p = Progressor()
    p.add("always P")
    with pytest.raises(DkError, match=says):
        for t, values in steps:
            p.step(t, values)


def test_a_bad_state_once_the_fast_step_took_over_is_the_same_error_and_changes_nothing() -> None:
    """The generated step takes `step`'s states itself after the first: a time not after the
    last, or a state without a feature, is still the one-line error, and is neither judged
    nor kept for robustness."""
    p = Progressor(robustness=True)
    p.add("always (X > 0)")
    for t in range(3):
        assert not p.step(t, {"X": 1})
    with pytest.raises(DkError, match="time 2 is not after the previous state's time 2"):
        p.step(2, {"X": -5})
    with pytest.raises(DkError, match="the state at time 3 has no value for X"):
        p.step(3, {"Y": -5})
    (v,) = p.step(3, {"X": -1})
    assert (v.verdict, v.time) == (False, 3)
    assert v.robustness is not None and v.robustness.value == -1


families = st.tuples(
    atoms,
    atoms,
    st.integers(0, 2),
    st.lists(st.one_of(st.integers(0, 5).map(str), st.just("oo")), min_size=1, max_size=4),
).map(
    lambda p: [
        f"always (({p[0]}) -> eventually[{p[2]}, {max(int(h), p[2]) if h != 'oo' else h}] ({p[1]}))"
        for h in p[3]
    ]
)


constants = st.one_of(
    st.integers(-1, 5).map(str),
    st.integers(0, 5).map(lambda c: f"-{c}"),
    st.integers(0, 4).map(lambda c: f"({c} - 1) * 2 + 1"),
)
thresholds = st.lists(
    st.tuples(st.sampled_from(["<", "<=", ">", ">="]), constants, st.booleans()).map(
        lambda p: f"always (X {p[0]} {p[1]})" if p[2] else f"always ({p[1]} {p[0]} X)"
    ),
    min_size=2,
    max_size=8,
)


@SETTINGS
@given(st.lists(st.one_of(formulas(), single), max_size=4), families, traces())
def test_formulas_sharing_one_progressor_each_keep_their_own_semantics(
    others: list[str], family: list[str], trace: Trace
) -> None:
    judged_alone_and_together([*others, *family], trace)


@SETTINGS
@given(st.lists(st.one_of(formulas(), single), max_size=3), thresholds, traces())
def test_invariants_sharing_a_feature_and_a_side_keep_their_own_semantics(
    others: list[str], family: list[str], trace: Trace
) -> None:
    """`always (X > c)` for many c share one sorted check (fused.Thresholds)."""
    judged_alone_and_together([*others, *family], trace)


def judged_alone_and_together(batch: list[str], trace: Trace) -> None:
    """Each formula of a batch on one progressor gets the verdict it has alone, at a state
    where its prefix already decides it."""
    p = Progressor()
    for f in batch:
        p.add(f)
    decided: dict[int, tuple[bool | None, int | None]] = {}
    for k, (t, values) in enumerate(trace):
        for v in p.step(t, values):
            n = next(i for i, f in enumerate(batch) if f == v.formula and i not in decided)
            decided[n] = (v.verdict, k)
    for v in p.finish():
        n = next(i for i, f in enumerate(batch) if f == v.formula and i not in decided)
        decided[n] = (v.verdict, None)
    assert sorted(decided) == list(range(len(batch)))
    for n, f in enumerate(batch):
        verdict, at = decided[n]
        parsed = parse_formula(f)
        assert verdict == holds(parsed, trace, 0), f
        if at is not None:
            assert verdict == holds(parsed, trace[: at + 1], 0), f


def test_times_print_as_exact_decimals_never_as_fractions() -> None:
    from dkreason.progress.witness import Clock

    assert Clock().time(Fraction(279258777611209011, 200000000)) == "1396293888.056045055"
    assert Clock(Fraction(1, 10**9)).time(1779999999970000029) == "1779999999.970000029"
    assert Clock().time(Fraction(1, 10)) == "0.1" and Clock().time(Fraction(1, 3)) == "1/3"
    from_start = Clock(Fraction(1, 10**9), lambda: 1779999999000000000)
    assert from_start.at(1779999999970000029) == "t+0.970000029 s"


def test_thresholds_sharing_a_feature_report_when_it_was_unknown() -> None:
    p = Progressor()
    for formula in ("always (X > 0)", "always (-1 < X)"):
        p.add(formula)
    for t, x in ((0, 1), (1, None), (2, None), (3, 2)):
        assert p.step(t, {"X": x}) == []
    verdicts = p.finish()
    assert [v.verdict for v in verdicts] == [None, None]
    assert all(
        [u.to_json() for u in v.unknown] == [{"feature": "X", "from": 1, "to": 2}] for v in verdicts
    )


# ---- one progression contract: the general engine and the fused monitors agree -----------

states = st.sampled_from(
    ["P", "Q", "not P", "X > 2", "X <= 1", "P and X > 2", "Q or X + 1 >= 3", "true", "false"]
)
windows = st.one_of(intervals.filter(bool), st.just(""))


@st.composite
def fusable(draw: st.DrawFn) -> str:
    """A formula the fused monitors take: an invariant, or a response in each way it is
    written (`->`, `not A or`, `A or`, none), or `always not always[a, b] S`."""
    a, b, window = draw(states), draw(states), draw(windows)
    return draw(
        st.sampled_from(
            [
                f"always ({a})",
                f"always (({a}) -> eventually{window} ({b}))",
                f"always (not ({a}) or eventually{window} ({b}))",
                f"always (({a}) or eventually{window} ({b}))",
                f"always (({a}) -> not always{window} ({b}))",
                f"always eventually{window} ({b})",
                f"always not always{window} ({b})",
            ]
        )
    )


conjunctions = st.lists(fusable(), min_size=1, max_size=3).map(
    lambda parts: " and ".join(f"({p})" for p in parts)
)
batches = st.lists(
    st.one_of(conjunctions, conjunctions, single, formulas(), families, thresholds), max_size=4
).map(lambda picks: [f for pick in picks for f in ([pick] if isinstance(pick, str) else pick)])


def engine_run(
    engine: str,
    batch: list[str],
    trace: Trace,
    end_of_data: str = "open",
    end: int = 0,
    passes: list[bool] | None = None,
) -> list[tuple[int | None, Any]]:
    """Every verdict of a batch judged together, with the index of the state that gave it;
    with `passes`, the stream also passes the middle of the k-th gap between states (after
    the last state: half a second after it, and the data ends no earlier) without a state
    when passes[k]."""
    p = Progressor(engine=engine, end_of_data=end_of_data)
    for f in batch:
        p.add(f)
    out: list[tuple[int | None, Any]] = []
    last = trace[-1][0] + end
    for k, (t, values) in enumerate(trace):
        out += [(k, v) for v in p.step(t, values)]
        if passes and k < len(passes) and passes[k]:
            gap = trace[k + 1][0] - t if k + 1 < len(trace) else Fraction(1)
            out += [(k, v) for v in p.advance(t + gap / 2)]
            last = max(last, t + gap / 2)
    return out + [(None, v) for v in p.finish(last)]


@SETTINGS
@given(
    batches.filter(bool),
    traces(),
    st.sampled_from(["open", "finite"]),
    st.sampled_from([0, 0, 1, 3]),
    st.lists(st.booleans(), max_size=7),
)
def test_both_engines_give_the_same_verdict_time_and_witness(
    batch: list[str], trace: Trace, end_of_data: str, end: int, passes: list[bool]
) -> None:
    """What the fused monitors decide, the general engine decides at the same state (or
    the same time the stream passed without a state) with the same witness (and the same
    unknown spans, and the same window left open where the data ends, at or after the last
    state), alone or beside other formulas."""
    assert engine_run("auto", batch, trace, end_of_data, end, passes) == engine_run(
        "general", batch, trace, end_of_data, end, passes
    )


@SETTINGS
@given(formulas(), traces(), st.lists(st.booleans(), max_size=7))
def test_a_stream_passing_a_window_without_a_state_decides_it_and_the_same_way(
    formula: str, trace: Trace, passes: list[bool]
) -> None:
    """Time passing without a state closes the windows that ended by then: the verdict is
    the one the states give, decided no later than without it."""
    passes = passes[: len(trace) - 1]  # between states: the data ends at the last one
    (verdict,) = [v for _, v in engine_run("auto", [formula], trace, passes=passes)]
    assert verdict.verdict == holds(parse_formula(formula), trace, 0)
    (alone,) = [(k, v) for k, v in engine_run("auto", [formula], trace)]
    if alone[0] is not None:
        k = next(k for k, v in engine_run("auto", [formula], trace, passes=passes))
        assert k is not None and k <= alone[0]


def test_a_window_closes_when_the_stream_passes_its_end() -> None:
    """A response's window [1, 3] ends between the states at 2 and 5: the stream passing 4
    without one decides it, there."""
    for engine in ("auto", "general"):
        p = Progressor(engine=engine)
        p.add("always (P -> eventually[0, 2] Q)")
        assert p.step(1, {"P": True, "Q": False}) == p.step(2, {"P": False, "Q": False}) == []
        assert p.deadline() == 3
        (v,) = p.advance(4)
        assert (v.verdict, v.time, v.witness) == (
            False,
            4,
            "violated at 4: P held at 1, but Q never held within [1, 3]",
        )


def test_the_general_engine_can_be_forced() -> None:
    formula = "always (P -> eventually[0, 2] Q)"
    auto, general = Progressor(), Progressor(engine="general")
    for p in (auto, general):
        p.add(formula)
    assert auto.fused.members and not auto.general.roots
    assert general.general.roots and not general.fused.members


def test_an_unknown_engine_is_a_one_line_error() -> None:
    with pytest.raises(DkError, match=r"^unknown engine 'fast' \(auto or general\)$"):
        Progressor(engine="fast")


@pytest.mark.parametrize("engine", ["auto", "general"])
@pytest.mark.parametrize(
    ("formula", "trace", "witness"),
    [
        (
            "always (X > 1)",
            [(0, {"X": 0})],
            "violated at 0: X > 1 was false at 0 (X = 0)",
        ),
        (
            "always (X > 1) and always (X > 0)",
            [(0, {"X": 2}), (1, {"X": 0})],
            "violated at 1: X > 1 was false at 1 (X = 0)",
        ),
        (
            "always (P -> eventually[0, 2] Q)",
            [
                (0, {"P": False, "Q": False}),
                (1, {"P": True, "Q": False}),
                (3, {"P": False, "Q": False}),
            ],
            "violated at 3: P held at 1, but Q never held within [1, 3]",
        ),
        (
            "always eventually[0, 1] Q",
            [(0, {"Q": False}), (1, {"Q": False})],
            "violated at 1: eventually[0, 1] Q is false at 0, because Q never held within [0, 1]",
        ),
        (
            "always not always[0, 1] P",
            [(0, {"P": True}), (2, {"P": True})],
            "violated at 2: always[0, 1] P is true at 0, because P held throughout [0, 1]",
        ),
        (
            "always ((X - Y) * (X - Y) > 0.25)",
            [(0, {"X": 1, "Y": 0}), (1, {"X": 1, "Y": 1})],
            "violated at 1: (X - Y) * (X - Y) > 0.25 was false at 1 (X = 1, Y = 1)",
        ),
    ],
)
def test_witnesses_lead_with_the_decision_and_quote_the_formula_exactly(
    engine: str, formula: str, trace: list[tuple[int, dict[str, Any]]], witness: str
) -> None:
    """When it was decided, then why: the leftmost failing part of a conjunction, a response's
    trigger and its window, each subformula quoted with the parentheses it needs."""
    p = Progressor(engine=engine)
    p.add(formula)
    (verdict,) = [v for t, values in trace for v in p.step(t, values)]
    assert verdict.verdict is False and verdict.witness == witness
