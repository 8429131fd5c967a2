"""The KnowledgeManager façade (thesis 5.3): topics added and removed persist atomically."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager, TopicSpec, Verdict
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


# ---- one front door: the façade runs what the CLI runs ---------------------------------------


FEDERATION = Path(__file__).resolve().parents[1] / "examples" / "federation.toml"
SPEEDING = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"
LATE = "always (Position[car2] >= 0)"


def _cli_events(capsys: pytest.CaptureFixture[str], argv: list[str]) -> list[dict[str, object]]:
    import json

    from dkreason.cli import main

    main(["monitor", "--config", str(FEDERATION), "--json", *argv])
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


@pytest.mark.parametrize(
    ("options", "policy"),
    [
        ([], {}),  # the defaults, which disagreed (150 late violations from the API)
        (
            ["--period", "1", "--max-age", "2", "--delay", "0"],
            {"sample_period": 1, "max_age": "2s", "delay_before_approximation": 0},
        ),
        (
            ["--delay", "500ms", "--start", "+10"],
            {"delay_before_approximation": 0.5, "start_time": "+10"},
        ),
    ],
)
def test_the_cli_and_the_facade_give_the_same_events(
    traffic: Path,
    capsys: pytest.CaptureFixture[str],
    options: list[str],
    policy: dict[str, Any],
) -> None:
    from dkreason import StreamPolicy

    cli = _cli_events(capsys, [*options, "--source", str(traffic), SPEEDING, LATE])
    run = KnowledgeManager.from_config(FEDERATION).monitor(
        [SPEEDING, LATE], traffic, StreamPolicy(**policy)
    )
    assert [e.to_json() for e in run] == cli
    assert any(e.get("verdict") is False for e in cli)


def test_a_run_shows_what_the_cli_prints_besides_the_events(traffic: Path) -> None:
    km = KnowledgeManager.from_config(FEDERATION)
    run = km.monitor(SPEEDING, traffic, remap=["/nowhere:=/elsewhere"])
    assert run.request == km.check_formula(SPEEDING)
    assert run.absent == {"platform2/carstopic2": ("Speed[car1]",)}  # car1 is not on platform 2
    assert run.clock == "header" and run.start == 0  # the recording's start, before reading
    events = list(run)
    assert [(e.time, e.t) for e in events if isinstance(e, Verdict)] == [(300.02, 300.02)] * 2
    with km.monitor(SPEEDING, [f"platform2={traffic}"]) as alone:  # platform 2's specs only
        assert set(alone.absent) >= {"platform1/topic3"}


def test_recordings_are_opened_by_one_public_function(traffic: Path) -> None:
    from dkreason.stream.binding import open_recordings

    with pytest.raises(DkError, match="'nowhere' is not a platform"):
        open_recordings([f"nowhere={traffic}"], ["platform1"])
    with pytest.raises(DkError, match="already remapped to /x"):
        open_recordings([traffic], remap=["/a:=/x", "/a:=/y"])
    with pytest.raises(DkError, match="clock 'wall'"):
        open_recordings([traffic], clock="wall")
    recordings = open_recordings([traffic], ["platform1"], remap={"/a": "/b"}, clock="record")
    try:
        assert recordings.clock == "record" and len(recordings.parts) == 1
    finally:
        recordings.close()
