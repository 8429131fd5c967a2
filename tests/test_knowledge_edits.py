"""The API for knowledge edits: platforms and mappings added and removed, sorts and objects
listed, topics added without saving, explanations rendered — all through KnowledgeManager and
dkreason.explain, no internal import."""

from __future__ import annotations

from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import DkError, ParseError
from dkreason.explain import render

FORMULA = "always (Altitude[uav2] > 10)"


def topics(km: KnowledgeManager, formula: str = FORMULA) -> list[tuple[str, str]]:
    (feature,) = km.check_formula(formula).features
    return [(t.platform, t.topic) for t in feature.topics]


def test_a_platform_and_a_mapping_are_added_and_removed(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "single.toml")
    assert topics(km) == [("platform1", "topic2")]
    km.add_platform(
        "platform3",
        scenario / "ontologies" / "platform3.owl",
        scenario / "specs" / "platform3.sslt",
    )
    assert km.platforms == ["platform1", "platform3"]
    assert topics(km) == [("platform1", "topic2")]  # joined by nothing yet
    km.add_mapping("platform1", "platform3", scenario / "mappings" / "platform1-platform3.cowl.xml")
    assert topics(km) == [("platform1", "topic2"), ("platform3", "uastopic5")]
    km.remove_mapping("platform1", "platform3")
    assert topics(km) == [("platform1", "topic2")]
    km.remove_platform("platform3")
    assert km.platforms == ["platform1"]


def test_a_mapping_waits_for_its_platform(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "single.toml")
    with pytest.raises(DkError, match="joins two known platforms"):
        km.add_mapping("platform1", "platform3", scenario / "mappings" / "x.cowl.xml")
    km.add_platform("platform3", scenario / "ontologies" / "platform3.owl")
    km.add_mapping("platform1", "platform3", scenario / "mappings" / "platform1-platform3.cowl.xml")
    with pytest.raises(DkError, match="a mapping platform1→platform3 is already known"):
        km.add_mapping(
            "platform1", "platform3", scenario / "mappings" / "platform1-platform3.cowl.xml"
        )
    with pytest.raises(DkError, match="no mapping platform3→platform1"):
        km.remove_mapping("platform3", "platform1")


def test_a_bad_mapping_changes_nothing(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "single.toml")
    km.add_platform(
        "platform2",
        scenario / "ontologies" / "platform2.owl",
        scenario / "specs" / "platform2.sslt",
    )
    with pytest.raises(ParseError, match="is absent in platform2"):  # platform 3's bridge rules
        km.add_mapping(
            "platform1", "platform2", scenario / "mappings" / "platform1-platform3.cowl.xml"
        )
    assert km.kb.mappings == () and km.kb.pending == ()
    km.add_mapping("platform1", "platform2", scenario / "mappings" / "platform1-platform2.cowl.xml")
    assert ("platform2", "carstopic1") in topics(km, "always (Speed[car1] > 1)")


def test_sorts_and_objects_are_listed(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    assert {"UAV", "Car", "Vehicle"} <= set(km.list_sorts())
    assert "UnmannedAircraftSystem" in km.list_sorts("platform3")
    assert km.list_objects() == ["car1", "car2", "car3", "uav1", "uav2"]
    assert km.list_objects("Car") == km.list_sort("Car") == ["car1", "car2", "car3"]


def test_a_topic_added_without_saving_leaves_the_file_alone(scenario: Path) -> None:
    specs = scenario / "specs" / "platform1.sslt"
    before = specs.read_text()
    km = KnowledgeManager.from_config(scenario / "single.toml")
    km.add_topic(
        "topic topic10:UavMsg contains Altitude(uav2) = msg.alt for uav2 = msg.id", save=False
    )
    assert ("platform1", "topic10") in topics(km)
    km.remove_topic("topic2", save=False)
    assert ("platform1", "topic2") not in topics(km)
    assert specs.read_text() == before


def test_an_explanation_is_rendered_as_text_json_or_dot(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    e = km.explain(FORMULA, feature="Altitude[uav2]")
    text = render(e)
    assert text.splitlines()[0] == "Altitude[uav2]"
    assert "  ✔ topic2 on platform1 (msg.id = 2)" in text.splitlines()
    assert "proof:" not in text and "proof:" in render(e, proof=True)
    assert render(e, "json").startswith('{"formula": "always (Altitude[uav2] > 10)"')
    assert render(e, "dot").startswith("digraph explanation {")
    with pytest.raises(DkError, match="no explanation format 'html'"):
        render(e, "html")
