"""The formula grammar (thesis spellings and ASCII) and feature extraction."""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dkreason.errors import ParseError
from dkreason.model import FeatureRef
from dkreason.parse.formula import (
    CALLS,
    Arith,
    Atom,
    Compare,
    Connective,
    Interval,
    Not,
    Num,
    Quant,
    Ref,
    Str,
    Temporal,
    Unary,
    Until,
    children,
    features,
    parse_formula,
    unparse,
)

from .conftest import formulas


def shape(formula: str) -> list[tuple[str, tuple[tuple[str, str | None], ...]]]:
    return [
        (f.name, tuple((a.name, a.sort) for a in f.args)) for f in features(parse_formula(formula))
    ]


def test_every_thesis_formula_and_its_ascii_twin_give_the_same_features() -> None:
    table = formulas()
    for key, text in table.items():
        if not key.endswith("-ascii"):
            assert shape(text) == shape(table[f"{key}-ascii"]), key


def test_quantified_variables_carry_their_sort_and_constants_none() -> None:
    assert shape("for all x in UAV y in Car □(Altitude[x] > 10 and Speed[x] > Speed[y])") == [
        ("Altitude", (("x", "UAV"),)),
        ("Speed", (("x", "UAV"),)),
        ("Speed", (("y", "Car"),)),
    ]
    assert shape("∀x in Car(Behind[car1, x])") == [("Behind", (("car1", None), ("x", "Car")))]
    assert shape("forall x in B, y in D (Z[x, y, e1])") == [
        ("Z", (("x", "B"), ("y", "D"), ("e1", None)))
    ]


def test_ascii_quantifier_with_colon_and_prefixed_sort() -> None:
    f = parse_formula("forall x in hr:UAV: always (Altitude[x] > 10)")
    assert isinstance(f, Quant) and f.sort == "hr:UAV" and isinstance(f.body, Temporal)


def test_prefix_operators_bind_tighter_than_and_but_looser_than_comparisons() -> None:
    f = parse_formula("always[0,300] S > 60 and P")
    assert isinstance(f, Connective) and f.op == "and"
    assert isinstance(f.left, Temporal) and isinstance(f.left.arg, Compare)


def test_implication_is_right_associative_and_iff_loosest() -> None:
    f = parse_formula("A -> B -> C <-> D")
    assert isinstance(f, Connective) and f.op == "<->"
    assert isinstance(f.left, Connective) and isinstance(f.left.right, Connective)


def test_quantifier_body_reaches_as_far_right_as_possible() -> None:
    f = parse_formula("forall x in S A[x] and B or C")
    assert isinstance(f, Quant) and isinstance(f.body, Connective) and f.body.op == "or"


def test_until_and_since_with_intervals_and_units_are_exact() -> None:
    f = parse_formula("P until[0ms, 12.25s] Q")
    assert isinstance(f, Until) and f.interval == Interval(Fraction(0), Fraction(49, 4))
    g = parse_formula("historically[1min, oo] not previous P since[250ms, 1h] Q")
    assert isinstance(g, Until) and g.op == "since"
    assert g.interval == Interval(Fraction(1, 4), Fraction(3600))
    assert isinstance(g.left, Temporal) and g.left.interval == Interval(Fraction(60), None)
    assert isinstance(g.left.arg, Not)


def test_single_letters_are_features_and_U_is_until() -> None:
    f = parse_formula("X[a] U G")
    assert isinstance(f, Until) and isinstance(f.left, Atom) and f.left.feature.name == "X"


@pytest.mark.parametrize(
    ("text", "column", "says"),
    [
        ("always (Altitude[uav1] > )", 26, "syntax error"),
        ("always (Altitude[uav1] > ", 26, "ends too early"),
        ("always (X + 3)", 9, "not a formula"),
        ("P until[5, 2] Q", 8, "empty interval"),
    ],
)
def test_syntax_errors_point_into_the_formula(text: str, column: int, says: str) -> None:
    with pytest.raises(ParseError) as err:
        parse_formula(text)
    assert err.value.span.column == column and says in str(err.value)


KNOWN = (
    "(functions: abs, min, max, sqrt, hypot; terms: prev, delta, rate, age; atoms: observed, fresh)"
)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("hypot(X[a]) > 1", "hypot takes 2 arguments, got 1"),
        ("min(X[a], 1, 2) > 1", "min takes 2 arguments, got 3"),
        ("sqrt(X[a], 2) > 1", "sqrt takes 1 argument, got 2"),
        ("abs() > 1", "abs takes 1 argument, got 0"),
        ("prev(X[a], 2) > 1", "prev takes 1 argument, got 2"),
        ("observed(X[a], 1s)", "observed takes 1 argument, got 2"),
        ("hypot(abs(X[a])) > 1", "hypot takes 2 arguments, got 1"),
        ("fresh(X[a])", "fresh(X, d) needs a duration"),
        ("fresh(X[a], Y[a])", "fresh(X, d) needs a duration"),
        ("avg(X[a]) > 1", f"unknown function avg {KNOWN}"),
        ("Höhe(1) > 1", f"unknown function Höhe {KNOWN}"),
    ],
)
def test_a_call_to_no_function_or_with_other_arguments_is_one_line_at_its_name(
    text: str, says: str
) -> None:
    with pytest.raises(ParseError) as err:
        parse_formula(f"always ({text})")
    assert str(err.value) == f"<formula>:1:9: {says}"


@given(
    st.sampled_from(sorted(n for group in CALLS.values() for n in group)),
    st.integers(0, 4),
    st.sampled_from(["X[a]", "3", "Y"]),
)
@settings(max_examples=200, deadline=None)
def test_every_call_parses_with_its_arity_and_names_itself_with_another(
    name: str, count: int, arg: str
) -> None:
    wanted = next(group[name] for group in CALLS.values() if name in group)
    args = [arg] * count if name != "fresh" or count != 2 else ["X[a]", "5s"]
    text = f"{name}({', '.join(args)})" + ("" if name in CALLS["atoms"] else " > 1")
    if count == wanted:
        if name in CALLS["functions"] or arg != "3":  # terms and atoms read a feature
            parse_formula(text)
        return
    with pytest.raises(ParseError) as err:
        parse_formula(text)
    assert str(err.value).startswith("<formula>:1:1: ") and str(err.value).count("\n") == 0
    said = "fresh(X, d) needs a duration" if name == "fresh" else f"{name} takes {wanted}"
    assert said in str(err.value)


# ---- formulas as text: what a witness quotes parses back to the same tree ---------------------

leaves = st.sampled_from(["X[a]", "Y", "Z[a, b]", "3", "1.5", "0.25", "2e-3"])


@st.composite
def exprs(draw: st.DrawFn, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        return draw(leaves)
    kind = draw(st.sampled_from(["+", "-", "*", "/", "neg", "abs"]))
    if kind == "neg":
        return f"-{draw(exprs(depth - 1))}"
    if kind == "abs":
        return f"abs({draw(exprs(depth - 1))})"
    text = f"{draw(exprs(depth - 1))} {kind} {draw(exprs(depth - 1))}"
    return f"({text})" if draw(st.booleans()) else text


windows = st.one_of(
    st.just(""),
    st.tuples(st.integers(0, 3), st.sampled_from(["", "ms", "min"]), st.integers(0, 4)).map(
        lambda p: f"[{p[0]}{p[1]}, {p[0] + p[2]}{p[1]}]"
    ),
    st.just("[0.5, oo]"),
)


@st.composite
def texts(draw: st.DrawFn, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(
            st.one_of(
                st.sampled_from(["P", "true", "false", 'S[a] == "o\\"k"', "observed(X[a])"]),
                st.tuples(
                    exprs(2), st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), exprs(2)
                ).map(" ".join),
            )
        )
    kind = draw(st.sampled_from(["not", "prefix", "binary", "until", "quant"]))
    sub = draw(texts(depth - 1))
    if kind == "not":
        return f"not ({sub})" if draw(st.booleans()) else f"not {sub}"
    if kind == "prefix":
        op = draw(st.sampled_from(["always", "eventually", "next", "once", "historically"]))
        return f"{op}{draw(windows)} ({sub})"
    if kind == "quant":
        return f"(forall x in S: {sub})"
    other = draw(texts(depth - 1))
    if kind == "until":
        return f"({sub}) {draw(st.sampled_from(['until', 'since']))}{draw(windows)} ({other})"
    op = draw(st.sampled_from(["and", "or", "->", "<->"]))
    return f"({sub} {op} {other})" if draw(st.booleans()) else f"({sub}) {op} ({other})"


def subtrees(node: Any) -> list[Any]:
    return [node, *(s for child in children(node) for s in subtrees(child))]


@settings(max_examples=400, deadline=None)
@given(texts())
def test_a_quoted_subformula_parses_back_to_the_same_tree(text: str) -> None:
    """Every subformula and subexpression of a parsed formula, as witnesses quote it."""
    for sub in subtrees(parse_formula(text)):
        if isinstance(sub, Num | Ref | Arith | Unary | Str):  # an expression: compared
            assert parse_formula(f"{unparse(sub)} > 0") == Compare(">", sub, Num(0))
        else:
            assert parse_formula(unparse(sub)) == sub, unparse(sub)


def test_quotes_have_the_parentheses_they_need_and_no_more() -> None:
    said = {
        "(X[t1] - X[t2]) * (X[t1] - X[t2]) + Y > 0.25": (
            "(X[t1] - X[t2]) * (X[t1] - X[t2]) + Y > 0.25"
        ),
        "always ((P -> eventually[0, 250ms] (Q)) and not (X > 2))": (
            "always ((P -> eventually[0, 0.25] Q) and not (X > 2))"
        ),
        "a - (b - c) > 1 and (a - b) - c > 1": "a - (b - c) > 1 and a - b - c > 1",
        "A -> (B -> C)": "A -> B -> C",
        "(A -> B) -> C": "(A -> B) -> C",
    }
    assert {text: unparse(parse_formula(text)) for text in said} == said


def test_a_name_before_a_minus_is_a_feature_not_a_quantified_sort() -> None:
    """`Y - 1`: after a bare name a minus may be a subtraction or (after `forall x in S`
    without its colon) a formula's unary minus; both read alike."""
    assert parse_formula("Y - 1 > 0") == Compare(
        ">", Arith("-", Ref(FeatureRef("Y", ())), Num(1)), Num(0)
    )
    assert unparse(parse_formula("forall x in S -X[x] > 1")) == "forall x in S: -X[x] > 1"


# Issue 34, item 7: property names often begin with a keyword (note, nextWaypoint, alwaysOn,
# onceFlag); a keyword is a keyword only as a whole word.
KEYWORDS = (
    "not", "always", "eventually", "next", "historically", "once", "previous", "until",
    "since", "U", "and", "or", "true", "false", "forall", "exists", "for", "all", "in",
    "abs", "observed", "inf", "oo",
)  # fmt: skip


@pytest.mark.parametrize(
    ("formula", "names"),
    [
        ("note[uav1]", [("note", (("uav1", None),))]),
        ("always nextX[me]", [("nextX", (("me", None),))]),
        ("alwaysOn[uav1] and onceFlag[uav1]",
         [("alwaysOn", (("uav1", None),)), ("onceFlag", (("uav1", None),))]),
        ("Uav[x] Until[x]", None),
    ],
)  # fmt: skip
def test_a_name_beginning_with_a_keyword_is_a_name(
    formula: str, names: list[tuple[str, tuple[tuple[str, str | None], ...]]] | None
) -> None:
    if names is None:
        with pytest.raises(ParseError):  # two atoms side by side: not `Uav[x] U ntil[x]`
            parse_formula(formula)
        return
    assert shape(formula) == names


def test_keywords_prefixing_names_in_a_quantified_formula_stay_names() -> None:
    assert shape("forall x in UAV (inflow[x] > 1 or orbit[x] > trueValue[x])") == [
        ("inflow", (("x", "UAV"),)),
        ("orbit", (("x", "UAV"),)),
        ("trueValue", (("x", "UAV"),)),
    ]


@given(
    st.sampled_from(KEYWORDS),
    st.from_regex(r"[A-Za-z0-9_]{1,6}", fullmatch=True),
    st.sampled_from(["", "not ", "always ", "next "]),
)
@settings(max_examples=300, deadline=None)
def test_any_name_a_keyword_begins_is_one_feature(keyword: str, rest: str, before: str) -> None:
    name = keyword + rest
    assert shape(f"{before}{name}[uav1] > 1") == [(name, (("uav1", None),))]
