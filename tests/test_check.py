"""Formula checks against the local ontology: errors point into the formula."""

from __future__ import annotations

from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import NameError_, SortError, SourceError

from .conftest import SCENARIOS


@pytest.fixture(scope="module")
def single() -> KnowledgeManager:
    assert SCENARIOS is not None
    return KnowledgeManager.from_config(SCENARIOS / "single.toml")


@pytest.mark.parametrize(
    ("formula", "error", "column", "says"),
    [
        ("always (Altitud[uav1] > 3)", NameError_, 9, "unknown feature 'Altitud'"),
        ("Altitude[uav9] > 3", NameError_, 10, "unknown object 'uav9'"),
        ("Close[uav1]", SortError, 1, "Close takes 2 arguments, not 1"),
        ("Altitude[car1] > 3", SortError, 10, "car1 is a Car, Altitude needs AerialVehicle"),
        ("forall x in Trucks: Speed[x] > 3", NameError_, 13, "unknown sort 'Trucks'"),
        (
            "forall x in Vehicle: GroundSpeed[x] > 3",
            SortError,
            34,
            "variable x ranges over Vehicle, which is not subsumed by UAV",
        ),
        ("Altitude[UAV] > 3", NameError_, 10, "'UAV' is a sort on platform1, not an object"),
    ],
)
def test_bad_formulas_are_errors_pointing_into_the_formula(
    single: KnowledgeManager, formula: str, error: type[SourceError], column: int, says: str
) -> None:
    with pytest.raises(error) as err:
        single.check_formula(formula)
    assert err.value.span.column == column and says in str(err.value)


def test_a_variable_of_a_subsort_is_accepted(single: KnowledgeManager) -> None:
    request = single.check_formula("forall x in UAV: Altitude[x] > 3")  # UAV ⊑ AerialVehicle
    assert [f.feature.args for f in request.features] == [("uav1",), ("uav2",)]


ESCORT = """
@prefix : <http://sea.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Ship a owl:Class .
:Boat a owl:Class .
:BinaryRelation a owl:Class .
:Escorts a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :BinaryRelation
    [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Ship ]
    [ a owl:Restriction ; owl:onProperty :arg2 ; owl:allValuesFrom :Boat ] ) ] .
:ship1 a owl:NamedIndividual, :Ship .
:boat1 a owl:NamedIndividual, :Boat .
"""


@pytest.mark.parametrize(
    ("formula", "column", "says"),
    [
        ("Escorts[ship1, ship1]", 16, "argument 2 of Escorts: ship1 is a Ship, Escorts needs Boat"),
        (
            "Escorts[ship1, boat1] and Escorts[boat1, boat1]",
            35,
            "argument 1 of Escorts: boat1 is a Boat, Escorts needs Ship",
        ),
    ],
)
def test_every_argument_must_fit_not_just_one(
    tmp_path: Path, formula: str, column: int, says: str
) -> None:
    (tmp_path / "sea.ttl").write_text(ESCORT)
    (tmp_path / "sea.toml").write_text('[platforms.sea]\nontology = "sea.ttl"\n')
    km = KnowledgeManager.from_config(tmp_path / "sea.toml")
    assert km.check_formula("Escorts[ship1, boat1]").features
    with pytest.raises(SortError) as err:
        km.check_formula(formula)
    assert err.value.span.column == column and says in str(err.value)
