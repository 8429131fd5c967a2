"""Adapters (issue 34): ontologies written with properties give the class pattern's features
through rule files (rules/adapters/), chosen per platform by `adapters = [...]`."""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.adapt import origin
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.explain import to_text
from dkreason.stream.recording import write_recording
from dkreason.workloads import property_style, sosa_style

from .conftest import REPO, SCENARIOS, formulas

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


def test_unrelated_domains_are_the_class_named_as_their_intersection(
    props: KnowledgeManager,
) -> None:
    """draft's domains Car and Boat: AmphibiousCar ≡ Car ⊓ Boat is its sort (carries' ranges
    alike); hull's UAV and Boat have no such class (a signature allows any of its sorts, never
    all of them): a warning."""
    assert signature(props, "draft") == (("AmphibiousCar",),)
    assert signature(props, "carries") == (("UAV",), ("AmphibiousCar",))
    made = props.kb.platforms[props.local].ontology.adapted[EX + "draft"]
    assert sorted(made.axioms) == [
        (EX + "draft", "http://www.w3.org/2000/01/rdf-schema#domain", EX + c)
        for c in ("Boat", "Car")
    ]
    warnings = props.check_formula("always (altitude[uav1] > 10)").warnings
    assert not any("draft" in w for w in warnings)


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


def test_an_adapter_reading_triples_by_a_predicate_it_finds_is_given_every_triple(
    tmp_path: Path,
) -> None:
    """Only the triples whose predicates an adapter names are asserted for it; a rule whose
    predicate is a variable bound by the ontology itself (a property used on an object, its
    sort the feature's) reads them all."""
    (tmp_path / "used.ttl").write_text(
        "@prefix : <http://www.example.com/used#> .\n"
        "@prefix owl: <http://www.w3.org/2002/07/owl#> .\n"
        ":UAV a owl:Class .\n:battery a owl:DatatypeProperty .\n"
        ":uav1 a owl:NamedIndividual, :UAV ; :battery 90 .\n",
        encoding="utf-8",
    )
    (tmp_path / "used.dl").write_text(
        ".decl used_on(Platform, Property, Sort)\n"
        "used_on(P, Q, S) <= triple(P, Q, 'rdf:type', 'owl:DatatypeProperty') & "
        "triple(P, O, Q, _V) & triple(P, O, 'rdf:type', S) & (S != 'owl:NamedIndividual')\n"
        "adapted_feature(P, Q, 1) <= used_on(P, Q, _S)\n"
        "adapted_arg(P, Q, 1, S) <= used_on(P, Q, S)\n",
        encoding="utf-8",
    )
    config = tmp_path / "c.toml"
    config.write_text(
        '[platforms.uav]\nontology = "used.ttl"\nadapters = ["used.dl"]\n', encoding="utf-8"
    )
    features = KnowledgeManager.from_config(config).kb.platforms["uav"].ontology.features
    battery = features["http://www.example.com/used#battery"]
    assert battery.arg_sorts == (("http://www.example.com/used#UAV",),)


STYLES = {"properties": property_style, "sosa": sosa_style}


def converted_config(
    tmp_path: Path, scenario: str, only: tuple[str, ...] = (), adapter: str = "properties"
) -> Path:
    """The thesis scenario with each platform's ontology (or `only` those) converted into the
    style `adapter` reads (property or SOSA style: ternary features, and in the SOSA style
    binary ones too, stay classes), read back through it; the others stay in the class style."""
    config = tomllib.loads((SCENARIOS / scenario).read_text(encoding="utf-8"))
    for name, table in config["platforms"].items():
        table["specs"] = str(SCENARIOS / table["specs"])
        table["ontology"] = str(SCENARIOS / table["ontology"])
        if only and name not in only:
            continue
        converted = tmp_path / f"{name}.ttl"
        converted.write_text(STYLES[adapter](Path(table["ontology"])), encoding="utf-8")
        table |= {"ontology": str(converted), "adapters": [adapter]}
    for mapping in config.get("mappings", []):
        mapping["file"] = str(SCENARIOS / mapping["file"])
    out = tmp_path / scenario
    out.write_text(toml(config), encoding="utf-8")
    return out


def toml(config: dict[str, Any]) -> str:
    lines = [f"local = {json.dumps(config['local'])}"] if "local" in config else []
    for name, table in config["platforms"].items():
        lines.append(f"[platforms.{name}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    for mapping in config.get("mappings", []):
        lines.append("[[mappings]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in mapping.items()]
    return "\n".join(lines) + "\n"


def requests(km: KnowledgeManager) -> dict[str, object]:
    """Every thesis formula's stream request as JSON, or the error it raises."""
    out: dict[str, object] = {}
    for key, formula in formulas().items():
        try:
            out[key] = km.check_formula(formula).to_json()
        except DkError as exc:
            out[key] = type(exc).__name__
    return out


@pytest.mark.parametrize("adapter", STYLES)
@pytest.mark.parametrize(
    "scenario", ["single.toml", "federation.toml", "chapter4.toml", "federation-xml.toml"]
)
def test_the_thesis_ontologies_in_the_property_and_sosa_styles_give_the_same_requests(
    tmp_path: Path, scenario: str, adapter: str
) -> None:
    """Acceptance: every formula of the thesis scenarios, local and federated."""
    classes = requests(KnowledgeManager.from_config(SCENARIOS / scenario))
    km = KnowledgeManager.from_config(converted_config(tmp_path, scenario, adapter=adapter))
    assert requests(km) == classes
    assert all(platform.ontology.adapted for platform in km.kb.platforms.values())
    assert sum(isinstance(r, dict) for r in classes.values()) >= 6


@pytest.mark.parametrize("converted", [("platform1",), ("platform2", "platform3")])
def test_a_property_style_platform_federates_with_class_style_ones_through_cowl(
    tmp_path: Path, converted: tuple[str, ...]
) -> None:
    """The COWL files join a property (platform3's Alt, an owl:DatatypeProperty) to a class
    (platform1's Altitude) by `equiv`, and objects by `same`, as between two classes."""
    classes = requests(KnowledgeManager.from_config(SCENARIOS / "federation.toml"))
    km = KnowledgeManager.from_config(converted_config(tmp_path, "federation.toml", converted))
    assert requests(km) == classes
    remote = {
        t["platform"]
        for f in km.check_formula(formulas()["F1"]).to_json()["features"]
        for t in f["topics"]
    }
    assert remote == {"platform1", "platform3"}


def test_an_adapter_of_ones_own_reads_a_vocabulary_not_shipped() -> None:
    """schema.org's domainIncludes/rangeIncludes, by a rule file beside the config: no Python."""
    km = KnowledgeManager.from_config(DATA / "schema-org.toml")
    assert topics(km, "always (speed[drone1] < 30 or follows[drone1, drone2])") == {
        "speed[drone1]": {("/drones", "msg.speed")},
        "follows[drone1, drone2]": {("/follow", "msg.follows")},
    }
    ont = km.kb.platforms["fleet"].ontology
    speed = ont.features["https://schema.org/speed"]
    assert sorted(speed.arg_sorts[0]) == [
        "http://www.example.com/fleet#Drone",
        "https://schema.org/Vehicle",
    ]
    assert str(ont.adapted["https://schema.org/speed"].rule).endswith("schema-org.dl:12")


SOSA = REPO / "tests" / "data" / "sosa-ssn"
ROOMS = "http://example.org/rooms#"
ROOM_TEMP = {"building_msgs/msg/RoomTemp": "int32 id\nfloat64 temperature\n"}


@pytest.fixture(scope="module")
def rooms() -> KnowledgeManager:
    return KnowledgeManager.from_config(SOSA / "rooms.toml")


def test_classes_of_observable_properties_are_features_of_their_features_of_interest(
    rooms: KnowledgeManager,
) -> None:
    """SOSA/SSN as written, importing sosa.ttl and ssn.ttl: tied by ∀isPropertyOf (Temperature),
    ∃hasProperty (Openness) or property individuals of objects (Noise)."""
    features = rooms.kb.platforms["building"].ontology.features
    assert {f.removeprefix(ROOMS): s.arg_sorts for f, s in features.items()} == {
        "Temperature": ((ROOMS + "Room",),),
        "Openness": ((ROOMS + "Door",),),
        "Noise": ((ROOMS + "Room",),),
    }
    assert topics(rooms, "always Openness[door1]") == {"Openness[door1]": {("/door", "msg.open")}}


def test_a_topic_named_by_its_sensor_carries_what_the_sensor_observes(
    rooms: KnowledgeManager,
) -> None:
    assert topics(rooms, "always (Temperature[room1] < 30 and Noise[room1] < 3)") == {
        "Temperature[room1]": {("/rooms", "msg.temperature"), ("/th1", "msg.temperature")},
        "Noise[room1]": {("/mic", "msg.level")},
    }
    assert topics(rooms, "always (Temperature[room2] < 30)") == {
        "Temperature[room2]": {("/rooms", "msg.temperature")}
    }


def test_an_explanation_cites_an_is_property_of_triple_as_told_not_reversed(
    tmp_path: Path,
) -> None:
    shutil.copytree(SOSA, tmp_path / "sosa")
    ttl = tmp_path / "sosa" / "rooms.ttl"
    told = ":room2_noise a owl:NamedIndividual, :Noise ; ssn:isPropertyOf :room2 .\n"
    ttl.write_text(ttl.read_text(encoding="utf-8") + told, encoding="utf-8")
    km = KnowledgeManager.from_config(tmp_path / "sosa" / "rooms.toml")
    said = origin(km.kb.platforms["building"].ontology, ROOMS + "Noise")
    assert "room2_noise ssn:isPropertyOf room2" in said
    assert "room2 ssn:isPropertyOf room2_noise" not in said
    assert "room1 ssn:hasProperty room1_noise" in said
    assert "room1 ssn:hasProperty room1_noise" in to_text(km.explain("always Noise[room1] < 3"))


def test_a_spec_of_a_sensors_observations_is_listed_as_written(
    rooms: KnowledgeManager, capsys: pytest.CaptureFixture[str]
) -> None:
    written = "topic /th1:RoomTemp contains observations of thermo1 = msg.temperature"
    assert main(["specs", "list", "--config", str(SOSA / "rooms.toml")]) == 0
    assert f"building: {written}\n" in capsys.readouterr().out
    assert rooms.get_topic_specification("/th1").features[0].observations


def test_untied_classes_and_untyped_property_individuals_are_one_warning_each(
    rooms: KnowledgeManager,
) -> None:
    warnings = rooms.check_formula("always Openness[door1]").warnings
    assert [w.split(" (")[0] for w in warnings] == ["building: Humidity", "building: room1_light"]
    assert "tied to no sort: add C ⊑ ∀ssn:isPropertyOf.S" in warnings[0]
    assert "typed by no class of observable properties" in warnings[1]


def test_a_sensor_that_observes_nothing_known_is_one_line_naming_the_spec(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    specs = tmp_path / "idle.sslt"
    specs.write_text(
        "topic /t:RoomTemp contains Temperature(room1) = msg.temperature\n"
        "topic /idle:RoomTemp contains observations of idle1 = msg.temperature\n",
        encoding="utf-8",
    )
    config = tmp_path / "c.toml"
    config.write_text(
        f'[platforms.b]\nontology = "{SOSA / "rooms.ttl"}"\nspecs = "{specs}"\n'
        'adapters = ["sosa"]\n',
        encoding="utf-8",
    )
    assert main(["match", "--config", str(config), "Temperature[room1] > 1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"{specs}:2:" in err and "sensor idle1 observes nothing known" in err


def room_recording(path: Path) -> Path:
    """thermo1's room warms from 20 to 34 degrees over 15 s (/th1, no id field needed)."""
    rows = [
        ("/th1", "building_msgs/msg/RoomTemp", t * 10**9, {"id": 1, "temperature": 20.0 + t})
        for t in range(15)
    ]
    write_recording(path, "bare-mcap", ROOM_TEMP, rows)
    return path


@pytest.mark.parametrize("config", [SOSA / "rooms.toml", DATA / "rooms-saref.toml"])
def test_sosa_and_saref_models_are_monitored_on_a_recording(tmp_path: Path, config: Path) -> None:
    """A spec naming the sensor (text for SOSA, XML for SAREF, saref:measuresProperty)."""
    km = KnowledgeManager.from_config(config)
    source = room_recording(tmp_path / "rooms.mcap")
    [verdict] = [
        e for e in km.monitor(["always (Temperature[room1] < 30)"], source) if hasattr(e, "verdict")
    ]
    assert (verdict.verdict, verdict.t) == (False, 10)


def test_explanations_cite_the_adapter_rule_and_the_told_axiom(props: KnowledgeManager) -> None:
    rule = next(
        n
        for n, line in enumerate(
            (REPO / "rules" / "adapters" / "properties.dl")
            .read_text(encoding="utf-8")
            .splitlines(),
            1,
        )
        if line.startswith("adapted_feature(P, X, 1)")
    )
    text = to_text(props.explain("always (altitude[uav1] > 10)"))
    assert (
        f"altitude on uav: adapter rule rules/adapters/properties.dl:{rule}, from altitude "
        f"rdfs:domain UAV ({DATA / 'uav-properties.ttl'})"
    ) in text


@pytest.mark.parametrize(
    ("name", "why"),
    [
        ("battery", "battery is no feature on uav: it has no rdfs:domain: add one"),
        ("comment", "comment is no feature on uav: it is an annotation property"),
        ("id", "id is no feature on uav: it is the id property"),
    ],
)
def test_a_formula_naming_a_property_that_became_no_feature_is_told_why(
    props: KnowledgeManager, name: str, why: str
) -> None:
    with pytest.raises(DkError, match=why):
        props.check_formula(f"always ({name}[uav1] > 1)")


def test_info_lists_each_platforms_features_with_signature_and_origin(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config = converted_config(tmp_path, "federation.toml", ("platform3",))
    assert main(["info", "--json", "--config", str(config)]) == 0
    found = {
        (f["platform"], f["feature"]): f for f in json.loads(capsys.readouterr().out)["features"]
    }
    assert found["platform1", "Close"]["origin"].startswith("class pattern (")
    assert found["platform3", "Near"]["signature"] == ["Aircraft", "Aircraft"]
    assert found["platform3", "Near"]["origin"].startswith(
        "adapter rule rules/adapters/properties.dl:"
    )
    assert (
        "from Near rdfs:domain Aircraft; Near rdfs:range Aircraft"
        in (found["platform3", "Near"]["origin"])
    )
    assert main(["info", "--config", str(config)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "platform platform3:" in lines
    assert any(line.split()[0] == "Near(Aircraft," for line in lines)


def test_a_platform_added_through_the_facade_takes_its_adapters(tmp_path: Path) -> None:
    """Its adapter runs in an engine of its own while the knowledge base's is loaded."""
    km = KnowledgeManager.from_config(SCENARIOS / "single.toml")
    converted = tmp_path / "platform3.ttl"
    converted.write_text(
        property_style(SCENARIOS / "ontologies" / "platform3.owl"), encoding="utf-8"
    )
    specs = SCENARIOS / "specs" / "platform3.sslt"
    with pytest.raises(DkError, match="unknown adapter 'sosaa'"):
        km.add_platform("platform3", converted, specs, adapters=["sosaa"])
    km.add_platform("platform3", converted, specs, adapters=["properties"])
    km.add_mapping(
        "platform1", "platform3", SCENARIOS / "mappings" / "platform1-platform3.cowl.xml"
    )
    assert ("uastopic4", "msg.height") in topics(km, "always (Altitude[uav1] > 1)")[
        "Altitude[uav1]"
    ]
