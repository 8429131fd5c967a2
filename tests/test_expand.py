"""Quantifier expansion and filters over a small maritime ontology (sameAs, ids, subsorts)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import MissingIdError

ONTOLOGY = """
@prefix : <http://sea.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
:Vessel a owl:Class .
:Ship a owl:Class ; rdfs:subClassOf :Vessel .
:Boat a owl:Class ; owl:equivalentClass :Dinghy .
:Dinghy a owl:Class ; rdfs:subClassOf :Vessel .
:Contact a owl:Class .
:UnaryRelation a owl:Class .
:Heading a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Vessel ] ) ] .
:ship7 a owl:NamedIndividual, :Ship .
:contact3 a owl:NamedIndividual, :Contact ; owl:sameAs :ship7 .
:skiff a owl:NamedIndividual, :Boat ; :id "S-1" .
:raft a owl:NamedIndividual, :Dinghy .
"""

SPECS = """topic track:Track contains Heading(Vessel) = msg.hdg for some Vessel = msg.id
topic own:Own contains Heading(ship7) = msg.hdg
"""


def km(tmp_path: Path, specs: str = SPECS) -> KnowledgeManager:
    (tmp_path / "sea.ttl").write_text(ONTOLOGY)
    (tmp_path / "sea.sslt").write_text(specs)
    (tmp_path / "sea.toml").write_text(
        '[platforms.sea]\nontology = "sea.ttl"\nspecs = "sea.sslt"\n'
    )
    return KnowledgeManager.from_config(tmp_path / "sea.toml")


def test_objects_that_are_same_as_each_other_expand_once_under_the_smallest_name(
    tmp_path: Path,
) -> None:
    request = km(tmp_path, "").check_formula("forall v in Vessel: Heading[v] > 0")
    assert [f.feature.args for f in request.features] == [("contact3",), ("raft",), ("skiff",)]


def test_expansion_includes_subsorts_equivalent_sorts_and_sorts_inherited_through_same_as(
    tmp_path: Path,
) -> None:
    manager = km(tmp_path, "")
    assert manager.list_sort("Boat") == ["raft", "skiff"]  # Boat ≡ Dinghy
    assert manager.list_sort("Ship") == ["contact3", "ship7"]  # contact3 sameAs ship7
    assert manager.list_sort("Vessel") == ["contact3", "raft", "ship7", "skiff"]


def test_a_sort_topic_appears_once_per_same_as_candidate_with_its_own_filter(
    tmp_path: Path,
) -> None:
    request = km(tmp_path).check_formula("Heading[ship7] > 0").to_json()
    got = {(t["topic"], tuple(t["filter"].items())) for t in request["features"][0]["topics"]}
    assert got == {("track", (("msg.id", 7),)), ("track", (("msg.id", 3),)), ("own", ())}


def test_id_property_wins_over_digits_and_may_be_a_string(tmp_path: Path) -> None:
    request = km(tmp_path).check_formula("Heading[skiff] > 0").to_json()
    assert request["features"][0]["topics"][0]["filter"] == {"msg.id": "S-1"}


def test_missing_id_where_a_filter_needs_one_names_object_and_topic(tmp_path: Path) -> None:
    with pytest.raises(MissingIdError, match="object raft .* topic track filters on msg.id"):
        km(tmp_path).check_formula("Heading[raft] > 0")


def test_a_constant_keeps_the_name_the_formula_writes(tmp_path: Path) -> None:
    request = km(tmp_path).check_formula("Heading[<http://sea.org/o#ship7>] > 0")
    assert request.features[0].feature.args == ("<http://sea.org/o#ship7>",)
