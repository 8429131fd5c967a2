"""The formula grammar (thesis spellings and ASCII) and feature extraction."""

from __future__ import annotations

from fractions import Fraction

import pytest

from dkreason.errors import ParseError
from dkreason.parse.formula import (
    Atom,
    Compare,
    Connective,
    Interval,
    Not,
    Quant,
    Temporal,
    Until,
    features,
    parse_formula,
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
