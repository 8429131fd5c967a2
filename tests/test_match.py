"""End to end: the thesis case studies reproduce their listings (expected/*.json)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import DkError

from .conftest import REPO, SCENARIOS, formulas, topic_sets

CASES = sorted((SCENARIOS / "expected").glob("*.json"))
_managers: dict[str, KnowledgeManager] = {}


def manager(config: str) -> KnowledgeManager:
    if config not in _managers:
        _managers[config] = KnowledgeManager.from_config(SCENARIOS / config)
    return _managers[config]


def twin(formula: str) -> str:
    table = formulas()
    key = next(k for k, v in table.items() if v == formula and not k.endswith("-ascii"))
    return table[f"{key}-ascii"]


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.stem)
@pytest.mark.parametrize("spelling", ["thesis", "ascii"])
@pytest.mark.parametrize("form", ["sslt", "xml"])
def test_thesis_case_matches_listing(case: Path, spelling: str, form: str) -> None:
    want = json.loads(case.read_text(encoding="utf-8"))
    config = want["config"] if form == "sslt" else want["config"].replace(".toml", "-xml.toml")
    formula = want["formula"] if spelling == "thesis" else twin(want["formula"])
    got = manager(config).check_formula(formula).to_json()
    assert topic_sets(got) == topic_sets(want)
    assert len(got["features"]) == len(want["features"])


def test_json_shape_is_exactly_the_documented_one() -> None:
    got = manager("single.toml").check_formula("always (Speed[uav1] > 50)").to_json()
    assert got == {"formula": "always (Speed[uav1] > 50)", "features": [
        {"feature": "Speed", "args": ["uav1"], "topics": [
            {"platform": "platform1", "topic": "topic1", "msgtype": "UavMsg",
             "field": "msg.spd", "filter": {"msg.id": 1}}]}]}


def test_remote_topics_say_what_they_were_matched_as() -> None:
    got = manager("federation.toml").check_formula("Altitude[uav2] > 3").to_json()
    (remote,) = [t for t in got["features"][0]["topics"] if t["platform"] != "platform1"]
    assert remote["as"] == {"feature": "Alt", "args": ["uas21"]}




def test_a_config_may_replace_the_shipped_matching_policy(scenario: Path) -> None:
    shutil.copy(REPO / "tests" / "data" / "strict.dl", scenario / "strict.dl")
    config = scenario / "strict.toml"
    config.write_text('replace_rules = true\nrules = ["rules/ontology.dl", "rules/signature.dl", '
                      '"rules/expansion.dl", "strict.dl"]\n'
                      + (scenario / "single.toml").read_text())
    formula = "always (Altitude[uav1] > 1)"
    shipped = KnowledgeManager.from_config(scenario / "single.toml").check_formula(formula)
    strict = KnowledgeManager.from_config(config).check_formula(formula)
    assert [t.topic for t in shipped.features[0].topics] == ["topic1", "topic2"]
    assert [(t.topic, t.filter) for t in strict.features[0].topics] == [
        ("topic1", (("msg.id", 1),))]


def test_a_replacing_policy_must_derive_what_dkreason_asks(scenario: Path) -> None:
    (scenario / "half.dl").write_text("object_id(P, O, V) <= name_digits(P, O, V)\n")
    config = scenario / "half.toml"
    config.write_text('replace_rules = true\nrules = ["half.dl"]\n'
                      + (scenario / "single.toml").read_text())
    with pytest.raises(DkError, match=r"schema.dl:\d+: the rules derive no expansion/3, which "
                                      r"dkreason asks for"):
        KnowledgeManager.from_config(config)
