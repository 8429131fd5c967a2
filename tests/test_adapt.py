"""Adapters (issue 34): ontologies written with properties give the class pattern's features
through rule files (rules/adapters/), chosen per platform by `adapters = [...]`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError

from .conftest import REPO

DATA = REPO / "tests" / "data" / "adapters"
EX = "http://www.example.com/props#"


@pytest.fixture(scope="module")
def props() -> KnowledgeManager:
    return KnowledgeManager.from_config(DATA / "uav-properties.toml")


def topics(km: KnowledgeManager, formula: str) -> dict[str, set[tuple[str, str]]]:
    """Per ground feature as shown: the (topic, field) pairs its request reads."""
    request = km.check_formula(formula).to_json()
    return {
        f"{f['feature']}[{', '.join(f['args'])}]": {(t["topic"], t["field"]) for t in f["topics"]}
        for f in request["features"]
    }


def signature(km: KnowledgeManager, name: str) -> tuple[tuple[str, ...], ...]:
    ont = km.kb.platforms[km.local].ontology
    return tuple(
        tuple(sorted(s.removeprefix(EX) for s in allowed))
        for allowed in ont.features[EX + name].arg_sorts
    )


def test_a_data_property_with_a_domain_is_a_unary_feature(props: KnowledgeManager) -> None:
    assert signature(props, "altitude") == (("UAV",),)
    assert topics(props, "always (altitude[uav1] > 10)") == {"altitude[uav1]": {("uav", "msg.alt")}}


def test_an_object_property_with_a_domain_and_a_range_is_a_binary_feature(
    props: KnowledgeManager,
) -> None:
    assert signature(props, "near") == (("UAV",), ("Car",))
    assert topics(props, "always near[uav1, car1]") == {"near[uav1, car1]": {("near", "msg.near")}}


def test_unions_inheritance_and_nested_domains_give_the_signature(
    props: KnowledgeManager,
) -> None:
    assert signature(props, "speed") == (("Car", "UAV"),)  # owl:unionOf
    assert signature(props, "airspeed") == (("Vehicle",),)  # its super-property's domain
    assert signature(props, "groundSpeed") == (("Car",),)  # Car and Vehicle: the most specific


def test_equivalent_properties_are_equivalent_features(props: KnowledgeManager) -> None:
    # height has no topic of its own: altitude's serve it, as equivalentClass makes them
    assert topics(props, "always (height[uav2] > 10)") == {"height[uav2]": {("uav", "msg.alt")}}


def test_annotation_properties_and_the_id_property_are_never_features(
    props: KnowledgeManager,
) -> None:
    features = props.kb.platforms[props.local].ontology.features
    assert EX + "comment" not in features
    assert EX + "id" not in features
    assert EX + "battery" not in features


def test_a_property_without_a_domain_is_one_warning_naming_it_and_what_to_add(
    props: KnowledgeManager, capsys: pytest.CaptureFixture[str]
) -> None:
    request = props.check_formula("always (altitude[uav1] > 10)")
    assert (
        f"uav: battery ({DATA / 'uav-properties.ttl'}) becomes no feature: it has no "
        "rdfs:domain: add one (the sort of its subjects) to make it a feature"
    ) in request.warnings
    assert any("follows" in w and "no rdfs:range" in w for w in request.warnings)
    assert any("hull" in w and "unrelated" in w for w in request.warnings)
    code = main(
        ["match", "--json", "--config", str(DATA / "uav-properties.toml"), "altitude[uav1] > 1"]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert sum("battery" in w for w in out["warnings"]) == 1


def test_an_unknown_adapter_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "c.toml"
    config.write_text(
        f'[platforms.uav]\nontology = "{DATA / "uav-properties.ttl"}"\nadapters = ["propertys"]\n',
        encoding="utf-8",
    )
    with pytest.raises(DkError, match="unknown adapter 'propertys' \\(shipped: properties"):
        KnowledgeManager.from_config(config)
    assert main(["match", "--config", str(config), "altitude[uav1] > 1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown adapter 'propertys'" in err


def test_without_adapters_a_property_is_no_feature(tmp_path: Path) -> None:
    config = tmp_path / "c.toml"
    config.write_text(
        f'[platforms.uav]\nontology = "{DATA / "uav-properties.ttl"}"\n', encoding="utf-8"
    )
    km = KnowledgeManager.from_config(config)
    assert not km.kb.platforms["uav"].ontology.features


def test_an_adapter_is_part_of_the_cache_key(tmp_path: Path) -> None:
    """A changed adapter file gives another knowledge base, not the cached one."""
    rules = tmp_path / "mine.dl"
    config = tmp_path / "c.toml"
    config.write_text(
        f'[platforms.uav]\nontology = "{DATA / "uav-properties.ttl"}"\nadapters = ["mine.dl"]\n',
        encoding="utf-8",
    )
    rules.write_text(
        "adapted_feature(P, X, 1) <= triple(P, X, 'rdfs:domain', '<http://www.example.com/props#UAV>')\n"
        "adapted_arg(P, X, 1, '<http://www.example.com/props#UAV>') <= adapted_feature(P, X, 1)\n",
        encoding="utf-8",
    )
    first = KnowledgeManager.from_config(config).kb.platforms["uav"].ontology.features
    rules.write_text(
        "adapted_feature(P, X, 1) <= triple(P, X, 'rdfs:domain', '<http://www.example.com/props#Car>')\n"
        "adapted_arg(P, X, 1, '<http://www.example.com/props#Car>') <= adapted_feature(P, X, 1)\n",
        encoding="utf-8",
    )
    second = KnowledgeManager.from_config(config).kb.platforms["uav"].ontology.features
    assert first.keys() != second.keys()
