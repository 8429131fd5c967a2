"""Formula checks against the local ontology: errors point into the formula."""

from __future__ import annotations

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import NameError_, SortError

from .conftest import SCENARIOS, needs_scenarios


@pytest.fixture(scope="module")
def single() -> KnowledgeManager:
    assert SCENARIOS is not None
    return KnowledgeManager.from_config(SCENARIOS / "single.toml")


@needs_scenarios
@pytest.mark.parametrize(("formula", "error", "column", "says"), [
    ("always (Altitud[uav1] > 3)", NameError_, 9, "unknown feature 'Altitud'"),
    ("Altitude[uav9] > 3", NameError_, 10, "unknown object 'uav9'"),
    ("Close[uav1]", SortError, 1, "Close takes 2 arguments, not 1"),
    ("Altitude[car1] > 3", SortError, 10, "car1 is a Car, Altitude needs AerialVehicle"),
    ("forall x in Trucks: Speed[x] > 3", NameError_, 13, "unknown sort 'Trucks'"),
    ("forall x in Vehicle: GroundSpeed[x] > 3", SortError, 34,
     "variable x ranges over Vehicle, which is not subsumed by UAV"),
    ("Altitude[UAV] > 3", NameError_, 10, "'UAV' is a sort on platform1, not an object"),
])
def test_bad_formulas_are_errors_pointing_into_the_formula(single, formula, error, column, says):
    with pytest.raises(error) as err:
        single.check_formula(formula)
    assert err.value.span.column == column and says in str(err.value)


@needs_scenarios
def test_a_variable_of_a_subsort_is_accepted(single):
    request = single.check_formula("forall x in UAV: Altitude[x] > 3")  # UAV ⊑ AerialVehicle
    assert [f.feature.args for f in request.features] == [("uav1",), ("uav2",)]
