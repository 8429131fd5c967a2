"""Names: local, prefixed and full IRIs, through an index."""

from __future__ import annotations

from typing import Any

import pytest

from dkreason.errors import NameError_, Span
from dkreason.names import NameIndex

INDEX = NameIndex(
    "p1",
    {"hr": "http://hr.org/o#", "ops": "http://ops.org/o#"},
    {
        "feature": ["http://hr.org/o#Heading", "http://ops.org/o#Heading", "http://hr.org/o#Speed"],
        "sort": ["http://hr.org/o#UAV"],
        "object": ["http://hr.org/o#uav1"],
    },
)
AT = Span("<formula>", 1, 5)


def test_unique_local_name_resolves() -> None:
    assert INDEX.resolve("Speed", ("feature",), AT) == "http://hr.org/o#Speed"


def test_shared_local_name_is_fine_until_used_unqualified_then_both_iris_are_named() -> None:
    with pytest.raises(NameError_) as err:
        INDEX.resolve("Heading", ("feature",), AT)
    assert "<http://hr.org/o#Heading> and <http://ops.org/o#Heading>" in str(err.value)


def test_prefixed_name_and_full_iri_select_one() -> None:
    assert INDEX.resolve("ops:Heading", ("feature",), AT) == "http://ops.org/o#Heading"
    assert INDEX.resolve("<http://hr.org/o#Heading>", ("feature",), AT) == "http://hr.org/o#Heading"


@pytest.mark.parametrize(
    ("written", "kinds", "says"),
    [
        ("Sped", ("feature",), "unknown feature 'Sped' on p1 (did you mean 'Speed'?)"),
        ("uav1", ("sort",), "'uav1' is an object on p1, not a sort"),
        ("zz:Heading", ("feature",), "unknown prefix 'zz'"),
    ],
)
def test_errors_say_what_is_wrong_with_the_name(
    written: str, kinds: tuple[Any, ...], says: str
) -> None:
    with pytest.raises(NameError_) as err:
        INDEX.resolve(written, kinds, AT)
    assert says in str(err.value) and str(err.value).startswith("<formula>:1:5")
