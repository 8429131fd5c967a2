"""The KnowledgeManager façade (thesis 5.3): topics added and removed persist atomically."""

from __future__ import annotations

from pathlib import Path

import pytest

from dkreason import KnowledgeManager, TopicSpec
from dkreason.errors import DkError, SortError

NEW = "topic topic10:UavMsg contains Altitude(uav2) = msg.alt for uav2 = msg.id"


@pytest.mark.parametrize("form", ["sslt", "xml"])
def test_added_topic_is_matched_and_saved_and_removing_restores_the_file(
    scenario: Path, form: str
) -> None:
    config = scenario / ("single.toml" if form == "sslt" else "single-xml.toml")
    specs = scenario / "specs" / f"platform1.{form}"
    before = specs.read_text()
    km = KnowledgeManager.from_config(config)
    km.add_topic(NEW)
    assert "topic10" in {t.topic for t in km.check_formula("Altitude[uav2] > 1").features[0].topics}
    reloaded = KnowledgeManager.from_config(config)
    assert reloaded.get_topic_specification("topic10") == km.get_topic_specification("topic10")
    reloaded.remove_topic("topic10")
    assert specs.read_text() == before


def test_removing_a_topic_edits_only_its_own_lines(scenario: Path) -> None:
    specs = scenario / "specs" / "platform1.sslt"
    specs.write_text("# platform 1 topics\n" + specs.read_text())
    km = KnowledgeManager.from_config(scenario / "single.toml")
    km.remove_topic("topic5")
    text = specs.read_text()
    assert text.startswith("# platform 1 topics\n") and "topic5" not in text
    assert "topic4" in text and "topic6" in text


def test_a_bad_spec_is_rejected_and_nothing_is_lost(scenario: Path) -> None:
    specs = scenario / "specs" / "platform1.sslt"
    before = specs.read_text()
    km = KnowledgeManager.from_config(scenario / "single.toml")
    with pytest.raises(SortError, match="car1 is a Car, Altitude needs AerialVehicle"):
        km.add_topic("topic topic10:M contains Altitude(car1) = msg.alt for car1 = msg.id")
    with pytest.raises(DkError, match="already exists"):
        km.add_topic(NEW.replace("topic10", "topic1"))
    assert specs.read_text() == before
    assert km.list_topics() == [f"topic{i}" for i in range(1, 10)]
    assert "topic10" not in km.list_topics()


def test_listing_and_lookup(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    assert km.list_topics("platform2") == ["carstopic1", "carstopic2", "carstopic3"]
    assert all(isinstance(s, TopicSpec) for s in km.list_topic_specifications("platform3"))
    assert km.list_sort("Vehicle") == ["car1", "car2", "car3", "uav1", "uav2"]
    assert km.list_sort("Aircraft", "platform3") == ["heli1", "heli2", "uas20", "uas21", "uas22"]
    with pytest.raises(DkError, match="no topic 'nope' on platform1"):
        km.get_topic_specification("nope")


def test_a_removed_topic_is_no_longer_matched_by_the_same_manager(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "single.toml")
    km.add_topic(NEW)
    km.remove_topic("topic10")
    km.remove_topic("topic2")
    topics = {t.topic for t in km.check_formula("Altitude[uav2] > 1").features[0].topics}
    assert "topic10" not in topics and "topic2" not in topics
