"""Federated matching across platforms joined by COWL bridge rules (thesis 4.3, 5.5, 6.2)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import ParseError

from .conftest import topic_sets

P1 = "http://www.example.com/ontology#"
P2 = "http://www.semanticweb.org/ontologies/2011/5/Distributed.owl#"
P3 = "http://www.semanticweb.org/ontologies/2011/6/distributed_uavs.owl#"
ONT = "http://www.co-ode.org/ontologies/ont.owl#"


def rule(kind: str, source: str, target: str) -> str:
    return (
        f'  <cowl:bridgeRule cowl:br-type="{kind}">\n'
        f'    <cowl:sourceConcept rdf:resource="{source}"/>\n'
        f'    <cowl:targetConcept rdf:resource="{target}"/>\n  </cowl:bridgeRule>\n'
    )


def add_rules(path: Path, *rules: str) -> None:
    text = path.read_text()
    path.write_text(text.replace("</cowl:mapping>", "".join(rules) + "</cowl:mapping>"))


def drop_rule(path: Path, source: str) -> None:
    text = path.read_text()
    path.write_text(
        re.sub(
            r'  <cowl:bridgeRule[^>]*>\s*<cowl:sourceConcept rdf:resource="'
            + re.escape(source)
            + r'"/>.*?</cowl:bridgeRule>\n',
            "",
            text,
            flags=re.S,
        )
    )


def add_to_ontology(path: Path, xml: str) -> None:
    text = path.read_text()
    path.write_text(text.replace("</rdf:RDF>", xml + "\n</rdf:RDF>"))


def topics(km: KnowledgeManager, formula: str) -> dict[str, set[tuple[str, str]]]:
    got = km.check_formula(formula).to_json()
    return {
        f"{f['feature']}[{', '.join(f['args'])}]": {
            (t["platform"], t["topic"]) for t in f["topics"]
        }
        for f in got["features"]
    }


def map_car3_to_a_truck(scenario: Path) -> None:
    """The issue's mis-mapping: platform 2 gains truck1 (a GroundVehicle, not an Automobile)
    and a bridge rule car3 same truck1."""
    add_to_ontology(
        scenario / "ontologies" / "platform2.owl",
        f'<owl:NamedIndividual rdf:about="{P2}truck1">'
        f'<rdf:type rdf:resource="{P2}GroundVehicle"/></owl:NamedIndividual>',
    )
    add_rules(
        scenario / "mappings" / "platform1-platform2.cowl.xml",
        rule("same", ONT + "car3", P2 + "truck1"),
    )


def test_a_mapping_into_the_wrong_sort_gives_no_topic_and_a_warning(scenario: Path) -> None:
    map_car3_to_a_truck(scenario)
    request = KnowledgeManager.from_config(scenario / "federation.toml").check_formula(
        "always (Speed[car3] > 60)"
    )
    assert {t.platform for t in request.features[0].topics} == {"platform1"}
    (warning,) = request.warnings
    assert "Speed[car3]" in warning and "platform2" in warning
    assert "truck1 is a GroundVehicle, Speed needs Automobile" in warning


def test_incompat_excludes_the_far_end_of_an_equivalence_chain_only(scenario: Path) -> None:
    add_rules(
        scenario / "mappings" / "platform1-platform3.cowl.xml",
        rule("incompat", P1 + "Altitude", P3 + "Alt"),
    )
    got = topics(
        KnowledgeManager.from_config(scenario / "federation.toml"),
        "Altitude[uav1] > Altitude[uav2]",
    )
    assert ("platform3", "uastopic4") in got["Altitude[uav1]"]  # Height: bridged, stays
    assert ("platform3", "uastopic5") not in got["Altitude[uav2]"]  # Alt ≡ Height, excluded


def test_a_mapping_file_written_from_the_remote_side_works_the_same(scenario: Path) -> None:
    forward = scenario / "mappings" / "platform1-platform3.cowl.xml"
    text = forward.read_text()
    swapped = re.sub(r"sourceConcept(.*?)\n(\s*)<cowl:targetConcept", r"TMP\1\n\2<cowl:SRC", text)
    swapped = swapped.replace("cowl:targetConcept", "cowl:sourceConcept")
    swapped = swapped.replace("cowl:TMP", "cowl:targetConcept").replace(
        "cowl:SRC", "cowl:sourceConcept"
    )
    (scenario / "mappings" / "platform3-platform1.cowl.xml").write_text(swapped)
    config = scenario / "federation.toml"
    forward_entry = (
        'source = "platform1"\ntarget = "platform3"\nfile = "mappings/platform1-platform3.cowl.xml"'
    )
    config.write_text(
        config.read_text().replace(
            forward_entry,
            (
                'source = "platform3"\ntarget = "platform1"\n'
                'file = "mappings/platform3-platform1.cowl.xml"'
            ),
        )
    )
    want = json.loads((scenario / "expected" / "federation-F1.json").read_text())
    got = KnowledgeManager.from_config(config).check_formula(want["formula"]).to_json()
    assert topic_sets(got) == topic_sets(want)


def test_subsumption_extension_adds_topics_of_more_specific_features(scenario: Path) -> None:
    # Replace the bridge Altitude ≡ Height by Height ⊑ Altitude, written from platform 3's side,
    # and add a local feature AirSpeed ⊑ Speed with a topic of its own.
    drop_rule(scenario / "mappings" / "platform1-platform3.cowl.xml", P1 + "Altitude")
    (scenario / "mappings" / "platform3-platform1.cowl.xml").write_text(
        '<cowl:mapping xmlns:cowl="http://www.itc.it/cowl#" '
        'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n'
        + rule("into", P3 + "Height", P1 + "Altitude")
        + "</cowl:mapping>\n"
    )
    add_to_ontology(
        scenario / "ontologies" / "platform1.owl",
        f"""
    <Class rdf:about="{P1}AirSpeed"><rdfs:subClassOf rdf:resource="{P1}Speed"/>
      <rdfs:subClassOf><Class><intersectionOf rdf:parseType="Collection">
        <rdf:Description rdf:about="{P1}UnaryRelation"/>
        <Restriction><onProperty rdf:resource="{P1}arg1"/>
          <allValuesFrom rdf:resource="{P1}UAV"/></Restriction>
      </intersectionOf></Class></rdfs:subClassOf></Class>""",
    )
    with (scenario / "specs" / "platform1.sslt").open("a") as specs:
        specs.write("topic topic10:UavMsg contains AirSpeed(uav1) = msg.as for uav1 = msg.id\n")
    config = scenario / "federation.toml"
    config.write_text(
        config.read_text() + '\n[[mappings]]\nsource = "platform3"\n'
        'target = "platform1"\nfile = "mappings/platform3-platform1.cowl.xml"\n'
    )
    formula = "Altitude[uav1] > Altitude[uav2] and Speed[uav1] > 50"
    default = topics(KnowledgeManager.from_config(config), formula)
    assert ("platform3", "uastopic4") not in default["Altitude[uav1]"]
    assert ("platform1", "topic10") not in default["Speed[uav1]"]

    config.write_text('rules = ["rules/extensions/subsumption.dl"]\n' + config.read_text())
    extended = topics(KnowledgeManager.from_config(config), formula)
    assert extended["Altitude[uav1]"] - default["Altitude[uav1]"] == {("platform3", "uastopic4")}
    assert extended["Altitude[uav2]"] - default["Altitude[uav2]"] == {("platform3", "uastopic5")}
    assert extended["Speed[uav1]"] - default["Speed[uav1]"] == {("platform1", "topic10")}


def test_a_platform_without_mappings_contributes_nothing_and_says_so(scenario: Path) -> None:
    config = scenario / "federation.toml"
    text = config.read_text()
    config.write_text(text[: text.index("[[mappings]]")])
    request = KnowledgeManager.from_config(config).check_formula("Speed[car1] > 3")
    assert {t.platform for t in request.features[0].topics} == {"platform1"}
    assert any("platform2 is joined to platform1 by no mapping file" in w for w in request.warnings)


@pytest.mark.parametrize(
    ("bad_rule", "says"),
    [
        (rule("equiv", P1 + "Nothing", P2 + "Speed"), "bridge rule 7 (equiv): source"),
        (rule("same", ONT + "car3", P2 + "Automobile"), "is a class in platform2"),
        (rule("sameish", ONT + "car3", P2 + "car11"), "br-type 'sameish' is not one of"),
        ('<cowl:bridgeRule cowl:br-type="equiv">\n', "malformed XML: mismatched tag"),
    ],
)
def test_bad_bridge_rules_name_the_file_and_the_rule(
    scenario: Path, bad_rule: str, says: str
) -> None:
    mapping = scenario / "mappings" / "platform1-platform2.cowl.xml"
    add_rules(mapping, bad_rule)
    with pytest.raises(ParseError) as err:
        KnowledgeManager.from_config(scenario / "federation.toml")
    assert str(err.value).startswith(str(mapping)) and says in str(err.value)


# ---- shared vocabularies (issue 15, item 5) ---------------------------------------------------

TURTLE = Path(__file__).parent / "data" / "turtles" / "turtle.ttl"


def fleet_of_two(tmp_path: Path, second_id: str = "") -> Path:
    """Two robots whose ontologies use the same IRIs (robot2 holds its own copy, where `me`
    may carry another id), each with its own specs, and no mapping file."""
    text = TURTLE.read_text()
    (tmp_path / "r1.ttl").write_text(
        text.replace(
            ":me a owl:NamedIndividual, :Robot .", ":me a owl:NamedIndividual, :Robot ; :id 1 ."
        )
    )
    (tmp_path / "r2.ttl").write_text(
        text.replace(
            ":me a owl:NamedIndividual, :Robot .",
            f":me a owl:NamedIndividual, :Robot ; :id {second_id or 1} .",
        )
    )
    (tmp_path / "r1.sslt").write_text(
        "topic pose:turtlesim/Pose contains X(me) = msg.x for me = msg.id\n"
    )
    (tmp_path / "r2.sslt").write_text(
        "topic odom:turtlesim/Pose contains X(Robot) = msg.x for some Robot = msg.id\n"
    )
    (tmp_path / "f.toml").write_text(
        'local = "robot1"\n[platforms.robot1]\nontology = "r1.ttl"\nspecs = "r1.sslt"\n'
        '[platforms.robot2]\nontology = "r2.ttl"\nspecs = "r2.sslt"\n'
    )
    return tmp_path / "f.toml"


def test_platforms_sharing_a_vocabulary_need_no_bridge_file(tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(fleet_of_two(tmp_path))
    request = km.check_formula("always (X[me] < 15)")
    assert {(t.platform, t.topic) for t in request.features[0].topics} == {
        ("robot1", "pose"),
        ("robot2", "odom"),
    }
    assert request.warnings == () and km.kb.warnings == []


def test_a_shared_object_is_filtered_by_each_platforms_own_id(tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(fleet_of_two(tmp_path, second_id="7"))
    request = km.check_formula("always (X[me] < 15)")
    assert {(t.platform, t.topic, t.filter) for t in request.features[0].topics} == {
        ("robot1", "pose", (("msg.id", 1),)),
        ("robot2", "odom", (("msg.id", 7),)),
    }


def test_the_docs_cowl_example_reads_every_bridge_type(tmp_path: Path) -> None:
    from dkreason.model import BRIDGE_TYPES
    from dkreason.parse.cowl import read_bridge_rules

    docs = Path(__file__).resolve().parents[1] / "docs"
    readme = (docs / "inputs.md").read_text(encoding="utf-8")
    (example,) = re.findall(r"```xml\n(<cowl:mapping.*?</cowl:mapping>)\n```", readme, re.S)
    (tmp_path / "m.cowl.xml").write_text(example)
    rules = read_bridge_rules(tmp_path / "m.cowl.xml")
    assert sorted(r.type for r in rules) == sorted(BRIDGE_TYPES)


def test_a_fleet_sharing_one_vocabulary_stores_links_of_the_local_platform_only(
    tmp_path: Path,
) -> None:
    """Twenty platforms sharing IRIs: only the local platform's links are kept (a context is
    the local platform and one other), so what a joining platform costs grows with the fleet,
    not with its square (issue 16: each join derived links between every pair)."""
    from dkreason.workloads import fleet

    fleet(tmp_path, 20)
    names = "".join(
        f'[platforms.p{n}]\nontology = "p{n}.ttl"\nspecs = "p{n}.sslt"\n' for n in range(1, 21)
    )
    (tmp_path / "fleet.toml").write_text(f'local = "m"\n[platforms.m]\nontology = "m.ttl"\n{names}')
    km = KnowledgeManager.from_config(tmp_path / "fleet.toml")
    sizes = {name: rows for name, (_, rows) in km.kb.engine.sizes().items()}
    assert sizes["shares_vocabulary"] == 20  # m with each p, never p with p
    request = km.check_formula("forall s in Sensor: always (Reading[s] < 1000)")
    assert sorted((t.platform, t.topic) for f in request.features for t in f.topics) == sorted(
        (f"p{n}", f"t{n}") for n in range(1, 21)
    )
