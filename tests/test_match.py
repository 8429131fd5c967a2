"""End to end: the thesis case studies reproduce their listings (expected/*.json)."""

from __future__ import annotations

import json

import pytest

from dkreason import KnowledgeManager

from .conftest import SCENARIOS, formulas, needs_scenarios, topic_sets

CASES = sorted((SCENARIOS / "expected").glob("*.json")) if SCENARIOS else []
_managers: dict[str, KnowledgeManager] = {}


def manager(config: str) -> KnowledgeManager:
    if config not in _managers:
        assert SCENARIOS is not None
        _managers[config] = KnowledgeManager.from_config(SCENARIOS / config)
    return _managers[config]


def twin(formula: str) -> str:
    table = formulas()
    key = next(k for k, v in table.items() if v == formula and not k.endswith("-ascii"))
    return table[f"{key}-ascii"]


@needs_scenarios
@pytest.mark.parametrize("case", CASES, ids=lambda p: p.stem)
@pytest.mark.parametrize("spelling", ["thesis", "ascii"])
@pytest.mark.parametrize("form", ["sslt", "xml"])
def test_thesis_case_matches_listing(case, spelling, form):
    want = json.loads(case.read_text(encoding="utf-8"))
    config = want["config"] if form == "sslt" else want["config"].replace(".toml", "-xml.toml")
    formula = want["formula"] if spelling == "thesis" else twin(want["formula"])
    got = manager(config).check_formula(formula).to_json()
    assert topic_sets(got) == topic_sets(want)
    assert len(got["features"]) == len(want["features"])


@needs_scenarios
def test_json_shape_is_exactly_the_documented_one():
    got = manager("single.toml").check_formula("always (Speed[uav1] > 50)").to_json()
    assert got == {"formula": "always (Speed[uav1] > 50)", "features": [
        {"feature": "Speed", "args": ["uav1"], "topics": [
            {"platform": "platform1", "topic": "topic1", "msgtype": "UavMsg",
             "field": "msg.spd", "filter": {"msg.id": 1}}]}]}


@needs_scenarios
def test_remote_topics_say_what_they_were_matched_as():
    got = manager("federation.toml").check_formula("Altitude[uav2] > 3").to_json()
    (remote,) = [t for t in got["features"][0]["topics"] if t["platform"] != "platform1"]
    assert remote["as"] == {"feature": "Alt", "args": ["uas21"]}
