"""Robustness (issue 30): discrete-time STL space robustness of a formula over the states
judged, with its critical atom and where that atom's values came from; checked against
rtamt's discrete-time offline evaluator on random formulas and uniformly sampled traces."""

from __future__ import annotations

import math
import os
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason.model import FeatureKey
from dkreason.parse.formula import parse_formula
from dkreason.progress.robustness import margins

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
