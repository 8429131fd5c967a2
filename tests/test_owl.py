"""Ontologies → told axioms (signatures as asserted, no OWL RL closure)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from dkreason.errors import ParseError
from dkreason.model import Ontology
from dkreason.names import local_name
from dkreason.parse.owl import read_ontology

from .conftest import SCENARIOS

HEAD = """<?xml version="1.0"?>
<rdf:RDF xmlns="http://x.org/o#" xml:base="http://x.org/o"
  xmlns:owl="http://www.w3.org/2002/07/owl#" xmlns:rdfs="http://www.w3.org/2000/01/rdf-schema#"
  xmlns:xsd="http://www.w3.org/2001/XMLSchema#"
  xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
"""


def signature(ont: Ontology, name: str) -> list[list[str]]:
    (sig,) = [s for iri, s in ont.features.items() if local_name(iri) == name]
    return [sorted(local_name(x) for x in arg) for arg in sig.arg_sorts]


def test_signatures_come_from_told_axioms_so_equivalent_features_keep_their_own() -> None:
    ont = read_ontology(SCENARIOS / "ontologies" / "platform1.owl", "p1")
    assert signature(ont, "GroundSpeed") == [["UAV"]]
    assert signature(ont, "Speed") == [["MovingObject"]]
    assert signature(ont, "Between") == [["Object"]] * 3


def test_union_of_sorts_per_argument() -> None:
    ont = read_ontology(SCENARIOS / "ontologies" / "chapter4.owl", "ch4")
    assert signature(ont, "Behind") == [["Car", "UAV"], ["Car", "UAV"]]


def test_any_rdf_syntax_rdflib_reads(tmp_path: Path) -> None:
    from rdflib import Graph

    turtle = tmp_path / "platform1.ttl"
    Graph().parse(SCENARIOS / "ontologies" / "platform1.owl").serialize(turtle, format="turtle")
    xml = read_ontology(SCENARIOS / "ontologies" / "platform1.owl", "p1")
    ttl = read_ontology(turtle, "p1")
    assert (ttl.features, ttl.individuals, set(ttl.types)) == (
        xml.features,
        xml.individuals,
        set(xml.types),
    )


def test_id_data_property_numeric_or_string_in_any_namespace(tmp_path: Path) -> None:
    path = tmp_path / "o.owl"
    path.write_text(
        HEAD
        + """
      <owl:Class rdf:about="http://x.org/o#Ship"/>
      <owl:NamedIndividual rdf:about="http://x.org/o#alpha">
        <rdf:type rdf:resource="http://x.org/o#Ship"/>
        <id xmlns="http://other.org/p#" rdf:datatype="http://www.w3.org/2001/XMLSchema#integer">7</id>
      </owl:NamedIndividual>
      <owl:NamedIndividual rdf:about="http://x.org/o#beta">
        <rdf:type rdf:resource="http://x.org/o#Ship"/><id>B-2</id>
      </owl:NamedIndividual>
    </rdf:RDF>"""
    )
    ids = read_ontology(path, "p").ids
    assert ids == {"http://x.org/o#alpha": 7, "http://x.org/o#beta": "B-2"}


def test_several_id_values_are_an_error_naming_the_object(tmp_path: Path) -> None:
    path = tmp_path / "o.owl"
    path.write_text(
        HEAD
        + """<owl:NamedIndividual rdf:about="http://x.org/o#alpha">
        <id>1</id><id>2</id></owl:NamedIndividual></rdf:RDF>"""
    )
    with pytest.raises(ParseError, match="alpha> has several id values"):
        read_ontology(path, "p")


@pytest.mark.parametrize(
    ("name", "text", "says"),
    [
        ("bad.ttl", "@prefix : <http://x#> .\n:a :b :c ;;; ]\n", "bad.ttl:2: malformed RDF"),
        (
            "bad.owl",
            HEAD + "<rdf:Description rdf:about='http://x#a'>",
            "bad.owl:7:1: malformed XML",
        ),
    ],
)
def test_malformed_rdf_names_file_and_line(tmp_path: Path, name: str, text: str, says: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ParseError) as err:
        read_ontology(path, "p")
    assert str(err.value).startswith(str(tmp_path / says.split(":")[0])) and says.split(": ", 1)[
        1
    ] in str(err.value)


# ---- OWL 2 declarations (issue 15, item 3) ----------------------------------------------------

DECLARED = """@prefix : <http://x.org/d#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
@prefix voaf: <http://purl.org/vocommons/voaf#> .
<http://x.org/d> a owl:Ontology, voaf:Vocabulary .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:hasPart a owl:ObjectProperty, owl:TransitiveProperty .
:near a owl:ObjectProperty, owl:SymmetricProperty .
:serial a owl:DatatypeProperty, owl:FunctionalProperty, owl:InverseFunctionalProperty .
:note a owl:AnnotationProperty .
:Celsius a rdfs:Datatype .
:UAV a owl:Class, owl:NamedIndividual .
:Höhe a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :UAV ] ) ] .
:drohne1 a owl:NamedIndividual, :UAV ; :id 1 .
"""


def declared(tmp_path: Path) -> Path:
    (tmp_path / "d.ttl").write_text(DECLARED, encoding="utf-8")
    (tmp_path / "d.sslt").write_text(
        "topic /hoehe:M contains Höhe(drohne1) = msg.h "
        "for drohne1 = msg.id\n"
        "topic /alle:M contains Höhe(UAV) = msg.h "
        "for some UAV = msg.id\n",
        encoding="utf-8",
    )
    (tmp_path / "d.toml").write_text(
        'local = "d"\n[platforms.d]\nontology = "d.ttl"\nspecs = "d.sslt"\n', encoding="utf-8"
    )
    return tmp_path / "d.toml"


def test_properties_datatypes_and_the_ontology_are_never_objects(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    km = KnowledgeManager.from_config(declared(tmp_path))
    assert km.list_sort("Thing") == ["UAV", "drohne1"]  # UAV is punned: also an object
    assert "Vocabulary" not in {local_name(s) for s in km.kb.platform("d").ontology.sorts}


def test_a_punned_name_is_a_sort_where_a_sort_is_expected_and_an_object_elsewhere(
    tmp_path: Path,
) -> None:
    from dkreason import KnowledgeManager

    km = KnowledgeManager.from_config(declared(tmp_path))
    request = km.check_formula("forall x in UAV: always (Höhe[x] > 10)")
    assert [f.feature.key for f in request.features] == [("Höhe", ("drohne1",))]
    assert sorted(t.topic for t in request.features[0].topics) == ["/alle", "/hoehe"]
    ont = km.kb.platform("d").ontology
    assert "http://x.org/d#UAV" in ont.sorts and "http://x.org/d#UAV" in ont.individuals


def test_non_ascii_local_names_need_no_quoting(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    km = KnowledgeManager.from_config(declared(tmp_path))
    (feature,) = km.check_formula("always (Höhe[drohne1] > 10)").features
    assert {t.topic for t in feature.topics} == {"/hoehe", "/alle"}


# ---- several files and imports (issue 15, item 1) ---------------------------------------------

SOSA = Path(__file__).parent / "data" / "sosa-ssn"


def station(
    tmp_path: Path, config: str = "", platform: str = "", ontology: str = '"weather.ttl"'
) -> Path:
    """The weather station (tests/data/sosa-ssn) copied with its catalog, a spec that only
    fits through SSN's axioms, and a config with `config` and `platform` lines added."""
    for f in SOSA.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "w.sslt").write_text(
        "topic /baro:M contains Reading(baro1) = msg.p for baro1 = msg.id\n"
    )
    (tmp_path / "w.toml").write_text(
        f'{config}\n[platforms.w]\nontology = {ontology}\nspecs = "w.sslt"\n{platform}\n'
    )
    return tmp_path / "w.toml"


def test_owl_imports_are_followed_through_a_protege_catalog(tmp_path: Path) -> None:
    """weather imports SSN, which imports SOSA: baro1, a sosa:Sensor, is an ssn:System only
    by SSN's axiom, so the spec fits and the sort expands."""
    from dkreason import KnowledgeManager

    km = KnowledgeManager.from_config(station(tmp_path))
    assert km.list_sort("System") == ["baro1", "baro2"]
    request = km.check_formula("forall s in System: always (Reading[s] > 900)")
    assert sorted(f.feature.key[1] for f in request.features) == [("baro1",), ("baro2",)]
    sorts = {local_name(s) for s in km.kb.platform("w").ontology.sorts}
    assert {"Sensor", "System", "Observation", "Deployment"} <= sorts  # SOSA's and SSN's


def test_without_the_import_the_spec_does_not_fit(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager
    from dkreason.errors import SortError

    config = station(tmp_path, platform='imports = "skip"')
    (tmp_path / "catalog-v001.xml").unlink()
    with pytest.raises(SortError, match="baro1 is a Sensor, Reading needs System"):
        KnowledgeManager.from_config(config)


def test_an_unresolved_import_names_the_importing_file_and_the_iri(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    config = station(tmp_path)
    (tmp_path / "catalog-v001.xml").unlink()
    with pytest.raises(
        ParseError,
        match=r"weather.ttl: owl:imports <http://www.w3.org/ns/ssn/>"
        r" is found neither",
    ):
        KnowledgeManager.from_config(config)


def test_a_config_table_resolves_imports_and_several_files_make_one_ontology(
    tmp_path: Path,
) -> None:
    from dkreason import KnowledgeManager

    config = station(
        tmp_path,
        config='[imports]\n"http://www.w3.org/ns/ssn/" = "ssn.ttl"\n'
        '"http://www.w3.org/ns/sosa/" = "sosa.ttl"',
        ontology='["weather.ttl", "extra.ttl"]',
    )
    (tmp_path / "catalog-v001.xml").unlink()
    (tmp_path / "extra.ttl").write_text(
        "@prefix owl: <http://www.w3.org/2002/07/owl#> .\n@prefix sosa: "
        "<http://www.w3.org/ns/sosa/> .\n<http://example.org/weather#baro3> a "
        "owl:NamedIndividual, sosa:Sensor .\n"
    )
    km = KnowledgeManager.from_config(config)
    assert km.list_sort("System") == ["baro1", "baro2", "baro3"]


def test_an_import_cycle_loads_each_ontology_once(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    config = station(tmp_path)
    sosa = tmp_path / "sosa.ttl"  # SOSA imports the weather station back
    sosa.write_text(
        sosa.read_text().replace(
            "sosa: a owl:Ontology ,",
            "sosa: owl:imports <http://example.org/weather> .\nsosa: a owl:Ontology ,",
        )
    )
    (tmp_path / "catalog-v001.xml").write_text(
        (tmp_path / "catalog-v001.xml")
        .read_text()
        .replace("</group>", '<uri name="http://example.org/weather" uri="weather.ttl"/></group>')
    )
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2"]


def test_a_skipped_import_is_a_warning(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    config = station(tmp_path, platform='imports = "skip"')
    (tmp_path / "w.sslt").write_text("")
    (tmp_path / "catalog-v001.xml").unlink()
    km = KnowledgeManager.from_config(config)
    (warning,) = km.kb.warnings
    assert "owl:imports <http://www.w3.org/ns/ssn/>" in warning and "skipped" in warning


def test_an_xxe_inside_an_imported_file_is_refused_naming_it(tmp_path: Path) -> None:
    from dkreason import KnowledgeManager

    config = station(tmp_path)
    (tmp_path / "ssn.owl").write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
        '<rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">&x;</rdf:RDF>\n'
    )
    catalog = tmp_path / "catalog-v001.xml"
    catalog.write_text(catalog.read_text().replace('uri="ssn.ttl"', 'uri="ssn.owl"'))
    with pytest.raises(Exception, match="ssn.owl"):
        KnowledgeManager.from_config(config)


@pytest.mark.parametrize(
    ("base", "ssn", "sosa"),
    [
        ('xml:base="elsewhere/"', "../ssn.ttl", "../sosa.ttl"),  # a group's base, relative
        ("", "file:{dir}/ssn.ttl", "file://{dir}/sosa.ttl"),
        ('xml:base="file:{dir}/"', "ssn.ttl", "./sosa.ttl"),
        ('xml:base="file:///nowhere/"', "file:{dir}/ssn.ttl", "{dir}/sosa.ttl"),
    ],
    ids=["relative-base", "file-uris", "absolute-base", "uri-over-base"],
)
def test_a_catalog_honours_xml_base_and_file_uris(
    tmp_path: Path, base: str, ssn: str, sosa: str
) -> None:
    from dkreason import KnowledgeManager

    config = station(tmp_path)
    (tmp_path / "catalog-v001.xml").write_text(
        '<?xml version="1.0"?>\n<catalog xmlns="urn:oasis:names:tc:entity:xmlns:xml:catalog">'
        f"<group {base.format(dir=tmp_path)}>"
        f'<uri name="http://www.w3.org/ns/ssn/" uri="{ssn.format(dir=tmp_path)}"/>'
        f'<uri name="http://www.w3.org/ns/sosa/" uri="{sosa.format(dir=tmp_path)}"/>'
        "</group></catalog>"
    )
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2"]


def test_a_changed_import_is_read_again_not_taken_from_the_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dkreason import KnowledgeManager

    monkeypatch.setenv("DKREASON_CACHE", str(tmp_path / "cache"))
    config = station(tmp_path)
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2"]
    ssn = tmp_path / "ssn.ttl"
    ssn.write_text(ssn.read_text() + "\n<http://example.org/weather#baro9> a sosa:Sensor .\n")
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2", "baro9"]


# ---- every common OWL syntax (issue 15, item 2) ----------------------------------------------

FUNCTIONAL = """Prefix(:=<http://x.org/s#>)
Ontology(<http://x.org/s>
Declaration(Class(:UAV))
Declaration(Class(:UnaryRelation))
Declaration(ObjectProperty(:arg1))
Declaration(Class(:Altitude))
SubClassOf(:Altitude ObjectIntersectionOf(:UnaryRelation ObjectAllValuesFrom(:arg1 :UAV)))
Declaration(NamedIndividual(:uav1))
ClassAssertion(:UAV :uav1)
)
"""
MANCHESTER = """Prefix: : <http://x.org/s#>
Ontology: <http://x.org/s>
Class: UAV
Class: UnaryRelation
ObjectProperty: arg1
Class: Altitude
    SubClassOf: UnaryRelation and (arg1 only UAV)
Individual: uav1
    Types: UAV
"""
OWL_XML = """<?xml version="1.0"?>
<Ontology xmlns="http://www.w3.org/2002/07/owl#" ontologyIRI="http://x.org/s">
  <Declaration><Class IRI="http://x.org/s#UAV"/></Declaration>
  <Declaration><Class IRI="http://x.org/s#UnaryRelation"/></Declaration>
  <Declaration><ObjectProperty IRI="http://x.org/s#arg1"/></Declaration>
  <Declaration><Class IRI="http://x.org/s#Altitude"/></Declaration>
  <SubClassOf><Class IRI="http://x.org/s#Altitude"/><ObjectIntersectionOf>
    <Class IRI="http://x.org/s#UnaryRelation"/>
    <ObjectAllValuesFrom><ObjectProperty IRI="http://x.org/s#arg1"/>
      <Class IRI="http://x.org/s#UAV"/></ObjectAllValuesFrom>
  </ObjectIntersectionOf></SubClassOf>
  <Declaration><NamedIndividual IRI="http://x.org/s#uav1"/></Declaration>
  <ClassAssertion><Class IRI="http://x.org/s#UAV"/><NamedIndividual IRI="http://x.org/s#uav1"/>
  </ClassAssertion>
</Ontology>
"""


@pytest.mark.parametrize(
    "text", [FUNCTIONAL, MANCHESTER, OWL_XML], ids=["functional", "manchester", "owl-xml"]
)
def test_owls_own_syntaxes_are_read_by_content_whatever_the_suffix(
    tmp_path: Path, text: str
) -> None:
    (tmp_path / "s.owl").write_text(text)
    ont = read_ontology(tmp_path / "s.owl", "s")
    assert signature(ont, "Altitude") == [["UAV"]]
    assert {local_name(o) for o in ont.individuals} == {"uav1"}


@pytest.mark.parametrize(
    ("text", "where", "says"),
    [
        (
            FUNCTIONAL.replace("ClassAssertion(:UAV :uav1)", "ClassAssertion(:UAV"),
            ":10:1:",
            "malformed OWL Functional Syntax",
        ),
        (MANCHESTER.replace("Types: UAV", "Types: and and"), ":9:19:", "malformed Manchester"),
        (OWL_XML.replace("</Ontology>", ""), ":16:1:", "malformed XML"),  # the XML hardening's
    ],
    ids=["functional", "manchester", "owl-xml"],
)
def test_a_malformed_owl_file_is_one_line_with_its_place(
    tmp_path: Path, text: str, where: str, says: str
) -> None:
    (tmp_path / "s.owl").write_text(text)
    with pytest.raises(ParseError) as error:
        read_ontology(tmp_path / "s.owl", "s")
    message = str(error.value)
    assert f"s.owl{where}" in message and says in message and "\n" not in message


# ---- OWL that cannot take the process down (issue 27, defects 3, 5 and 8) -------------------


@pytest.mark.parametrize("kind", ["ofn", "omn", "omn-chain", "owx"])
def test_deep_nesting_is_one_line_and_exit_2_not_a_signal(tmp_path: Path, kind: str) -> None:
    from dkreason.workloads import nested_owl

    from .conftest import REPO

    (tmp_path / "deep.owl").write_text(nested_owl(kind, 10_000))
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "deep.owl"\n')
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dkreason.cli",
            "match",
            "--config",
            str(tmp_path / "c.toml"),
            "P[a]",
        ],
        capture_output=True,
        text=True,
        env=os.environ | {"PYTHONPATH": str(REPO / "src")},
    )
    assert done.returncode == 2, (done.returncode, done.stderr[-300:])
    assert done.stderr.count("\n") == 1 and "deep.owl:" in done.stderr
    assert "nested deeper than" in done.stderr


# A large document is read a piece at a time (parse/owlsplit.py); PIECE is made small here.
LARGE_FUNCTIONAL = FUNCTIONAL.replace(
    "Ontology(<http://x.org/s>\n",
    "Prefix(rdfs:=<http://www.w3.org/2000/01/rdf-schema#>)\n"
    'Ontology(<http://x.org/s>\nImport(<http://x.org/none>)\nAnnotation(rdfs:comment "a (b")\n',
).replace(
    "ClassAssertion(:UAV :uav1)\n",
    "".join(
        f'ClassAssertion(:UAV :u{k}) # ) comment\nAnnotationAssertion(rdfs:label :u{k} "x) (")\n'
        for k in range(40)
    ),
)
LARGE_MANCHESTER = (
    "Prefix: rdfs: <http://www.w3.org/2000/01/rdf-schema#>\n"
    + MANCHESTER
    + "".join(
        f'Individual: u{k}\n    Annotations: rdfs:label "a\nClass: Fake"\n    Types: UAV\n'
        for k in range(40)
    )
)


@pytest.mark.parametrize(
    ("name", "text"), [("s.ofn", LARGE_FUNCTIONAL), ("s.omn", LARGE_MANCHESTER)]
)
def test_a_large_document_read_in_pieces_gives_the_triples_read_at_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, text: str
) -> None:
    from dkreason.parse import owlsplit
    from dkreason.parse.owl import read_sources

    (tmp_path / name).write_text(text)
    whole = set(read_sources([tmp_path / name], skip=True).graph)
    monkeypatch.setattr(owlsplit, "PIECE", 200)
    assert len(owlsplit.pieces(text, name[-3:])) > 5
    assert _isomorphic(set(read_sources([tmp_path / name], skip=True).graph), whole)


def _isomorphic(a: set[Any], b: set[Any]) -> bool:
    from rdflib import Graph
    from rdflib.compare import isomorphic

    one, two = Graph(), Graph()
    for triple in a:
        one.add(triple)
    for triple in b:
        two.add(triple)
    return isomorphic(one, two)


@pytest.mark.parametrize(
    ("name", "text", "where"),
    [
        (
            "s.ofn",
            LARGE_FUNCTIONAL.replace("ClassAssertion(:UAV :u33)", "ClassAssertion(:UAV"),
            ":79:1:",
        ),
        (
            "s.omn",
            LARGE_MANCHESTER.replace("u33\n    Annotations", "u33\n Types: and and\n"),
            ":145:2:",
        ),
    ],
)
def test_an_error_in_a_later_piece_is_placed_in_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, text: str, where: str
) -> None:
    from dkreason.parse import owlsplit

    (tmp_path / name).write_text(text)
    with pytest.raises(ParseError) as whole:
        read_ontology(tmp_path / name, "s")
    monkeypatch.setattr(owlsplit, "PIECE", 200)
    with pytest.raises(ParseError) as pieces:
        read_ontology(tmp_path / name, "s")
    assert str(pieces.value) == str(whole.value)
    assert where in str(whole.value)


def test_anonymous_individuals_keep_a_document_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    from dkreason.parse import owlsplit

    monkeypatch.setattr(owlsplit, "PIECE", 200)
    text = LARGE_FUNCTIONAL.replace(":u3)", "_:x)").replace(":u4)", "_:x)")
    assert owlsplit.pieces(text, "ofn") == [text]


@pytest.mark.parametrize("kind", ["ofn", "omn", "omn-chain", "owx"])
def test_nesting_as_deep_as_real_ontologies_go_is_read(tmp_path: Path, kind: str) -> None:
    from dkreason.workloads import nested_owl

    (tmp_path / "deep.owl").write_text(nested_owl(kind, 20))
    assert "http://example.org/hostile#A0" in read_ontology(tmp_path / "deep.owl", "p").sorts


def test_owl_text_that_names_a_file_is_not_read_as_that_file(tmp_path: Path) -> None:
    """py-horned-owl opens a file when the text it is given is a path: never here."""
    (tmp_path / "real.ofn").write_text(FUNCTIONAL)
    (tmp_path / "s.ofn").write_text(str(tmp_path / "real.ofn"))
    with pytest.raises(ParseError, match="s.ofn"):
        read_ontology(tmp_path / "s.ofn", "s")


@pytest.mark.parametrize("name", ["s.owl", "s.ofn", "s.omn", "s.owx"])
def test_a_utf8_bom_is_read(tmp_path: Path, name: str) -> None:
    text = {"s.ofn": FUNCTIONAL, "s.omn": MANCHESTER, "s.owx": OWL_XML}.get(name, MANCHESTER)
    (tmp_path / name).write_text("\ufeff" + text, encoding="utf-8")
    ont = read_ontology(tmp_path / name, "s")
    assert signature(ont, "Altitude") == [["UAV"]]


@pytest.mark.parametrize(
    "text",
    ["", "  \n", "Prefix: : <http://x.org/s#>\n", MANCHESTER[: MANCHESTER.index("Ontology:") + 5]],
    ids=["empty", "blank", "prefixes-only", "cut-in-the-header"],
)
def test_an_empty_or_cut_manchester_file_is_an_error(tmp_path: Path, text: str) -> None:
    (tmp_path / "s.omn").write_text(text)
    with pytest.raises(ParseError, match="s.omn"):
        read_ontology(tmp_path / "s.omn", "s")


ENTITIES = (
    OWL_XML.replace("http://x.org/s#", "&s;")
    .replace(
        '<?xml version="1.0"?>\n',
        '<?xml version="1.0"?>\n<!DOCTYPE Ontology [\n  <!ENTITY s "http://x.org/s#">\n'
        '  <!ENTITY tricky "a ] > b">\n]>\n',
    )
    .replace("<Declaration>", "<!-- &tricky; --><Declaration>", 1)
)


@pytest.mark.parametrize("name", ["s.owl", "s.owx"])
def test_owl_xml_with_internal_entities_is_read(tmp_path: Path, name: str) -> None:
    (tmp_path / name).write_text(ENTITIES)
    ont = read_ontology(tmp_path / name, "s")
    assert signature(ont, "Altitude") == [["UAV"]]
    assert ont.individuals == {"http://x.org/s#uav1"}


@pytest.mark.parametrize(
    "text",
    [
        OWL_XML.replace("?>\n", "?>\n<!--" + "x" * 70_000 + "-->\n", 1),
        FUNCTIONAL.replace("Ontology(", "#" + "x" * 70_000 + "\nOntology(", 1),
    ],
    ids=["owl-xml", "functional"],
)
def test_content_is_sniffed_past_a_preamble_of_any_length(tmp_path: Path, text: str) -> None:
    (tmp_path / "s.owl").write_text(text)
    assert signature(read_ontology(tmp_path / "s.owl", "s"), "Altitude") == [["UAV"]]


@pytest.mark.parametrize(
    "text",
    ["<!DOCTYPE x [" + "[" * 65_000, "<!DOCTYPE x [" + '<!ENTITY a "' * 20_000, "<!--" * 30_000],
    ids=["brackets", "open-quotes", "open-comments"],
)
def test_a_hostile_preamble_is_one_line_in_one_pass(tmp_path: Path, text: str) -> None:
    (tmp_path / "s.owl").write_text(text)
    with pytest.raises(ParseError) as error:
        read_ontology(tmp_path / "s.owl", "s")
    assert "\n" not in str(error.value)


# ---- entailed sort membership (issue 15, item 4) ----------------------------------------------

ENTAILING = """@prefix : <http://x.org/e#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Robot a owl:Class .
:Drone a owl:Class ; rdfs:subClassOf :Robot .
:Payload a owl:Class .
:Battery a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
:flies a owl:ObjectProperty ; rdfs:domain :Drone .
:pilots a owl:ObjectProperty ; rdfs:range :Drone .
:carries a owl:ObjectProperty .
:Carrier a owl:Class ; rdfs:subClassOf :Robot ; owl:equivalentClass [ a owl:Restriction ;
    owl:onProperty :carries ; owl:someValuesFrom :Payload ] .
:colour a owl:ObjectProperty .
:Blue a owl:Class ; rdfs:subClassOf :Robot ; owl:equivalentClass [ a owl:Restriction ;
    owl:onProperty :colour ; owl:hasValue :blue ] .
:BlueDrone a owl:Class ; owl:equivalentClass [ a owl:Class ; owl:intersectionOf ( :Blue :Drone ) ] .
:memberOf a owl:ObjectProperty .
:fleetOf a owl:ObjectProperty .
:inFleet a owl:ObjectProperty ; owl:propertyChainAxiom ( :memberOf :fleetOf ) ;
    rdfs:domain :FleetMember .
:FleetMember a owl:Class ; rdfs:subClassOf :Robot .
:tag a owl:ObjectProperty, owl:InverseFunctionalProperty .
:d1 a owl:NamedIndividual ; :flies :sky .
:alice a owl:NamedIndividual ; :pilots :d2 .
:d2 a owl:NamedIndividual .
:d3 a owl:NamedIndividual ; :carries :p1 .
:p1 a owl:NamedIndividual, :Payload .
:d4 a owl:NamedIndividual ; :colour :blue .
:d5 a owl:NamedIndividual, :Drone ; :colour :blue .
:d6 a owl:NamedIndividual ; :memberOf :squad1 .
:squad1 a owl:NamedIndividual ; :fleetOf :f1 .
:d7 a owl:NamedIndividual, :Robot ; :tag :t7 .
:drone7 a owl:NamedIndividual ; :tag :t7 .
:sky a owl:NamedIndividual . :blue a owl:NamedIndividual . :f1 a owl:NamedIndividual .
:t7 a owl:NamedIndividual .
"""


def entailing(tmp_path: Path, reasoning: str = "owl-rl") -> Any:
    from dkreason import KnowledgeManager

    (tmp_path / "e.ttl").write_text(ENTAILING)
    (tmp_path / "e.sslt").write_text(
        "topic /battery:M contains Battery(Robot) = msg.b for some Robot = msg.id\n"
    )
    (tmp_path / "e.toml").write_text(
        f'[platforms.e]\nontology = "e.ttl"\nspecs = "e.sslt"\nreasoning = "{reasoning}"\n'
    )
    return KnowledgeManager.from_config(tmp_path / "e.toml")


@pytest.mark.parametrize(
    ("sort", "members", "because"),
    [
        ("Drone", ["d1", "d2", "d5"], "flies rdfs:domain Drone"),  # domain (d1), range (d2)
        ("Carrier", ["d3"], "Carrier ≡ carries some Payload"),  # someValuesFrom
        ("Blue", ["d4", "d5"], "Blue ≡ colour value blue"),  # hasValue
        ("BlueDrone", ["d5"], "BlueDrone ≡ Blue ⊓ Drone"),  # intersection
        ("FleetMember", ["d6"], "inFleet rdfs:domain FleetMember"),  # property chain, then domain
    ],
    ids=["domain-range", "some", "value", "intersection", "chain"],
)
def test_owl_rl_entails_memberships_and_says_from_which_axiom(
    tmp_path: Path, sort: str, members: list[str], because: str
) -> None:
    km = entailing(tmp_path)
    assert km.list_sort(sort) == members
    reasons = km.kb.platform("e").ontology.entailed.values()
    assert any(because in r for r in reasons), list(reasons)


def test_owl_rl_entails_same_as(tmp_path: Path) -> None:
    km = entailing(tmp_path)
    ont = km.kb.platform("e").ontology
    pair = next(p for p in ont.same_as if set(p) == {"http://x.org/e#d7", "http://x.org/e#drone7"})
    assert "tag is inverse functional" in ont.entailed[pair]
    reps = {str(r[2]) for o in pair for r in km.kb.engine.query("same_rep", "e", o, None)}
    assert len(reps) == 1  # one sameAs class: drone7 reads d7's topics and back


def test_without_reasoning_only_told_memberships_count(tmp_path: Path) -> None:
    km = entailing(tmp_path, "none")
    assert km.list_sort("Drone") == ["d5"] and km.list_sort("Carrier") == []


def test_an_entailed_membership_is_explained_with_its_axiom(tmp_path: Path) -> None:
    from dkreason import explain

    km = entailing(tmp_path)
    text = explain.to_text(km.explain("always (Battery[d1] > 20)"))
    assert "entailed by OWL RL from flies rdfs:domain Drone" in text


def test_signatures_stay_told_under_owl_rl(tmp_path: Path) -> None:
    """Thesis listing 6.3: GroundSpeed ≡ Speed keeps its own signature with reasoning on."""
    from dkreason import KnowledgeManager

    (tmp_path / "p.toml").write_text(
        f'[platforms.p1]\nontology = "{SCENARIOS}/ontologies/platform1.owl"\nreasoning = "owl-rl"\n'
    )
    ont = KnowledgeManager.from_config(tmp_path / "p.toml").kb.platform("p1").ontology
    assert signature(ont, "GroundSpeed") == [["UAV"]]
    assert signature(ont, "Speed") == [["MovingObject"]]


def agrees_with_owlrl(km: Any, files: list[Path]) -> None:
    """owlrl is the oracle: every named object's sorts, told and entailed, closed under the
    told hierarchy, are the sorts its OWL 2 RL closure types it with, and its sameAs class is
    the objects the closure says are sameAs it."""
    import owlrl
    from rdflib import URIRef
    from rdflib.namespace import OWL, RDF

    from dkreason.parse.owl import read_sources

    (platform,) = km.kb.platforms
    ont = km.kb.platform(platform).ontology
    closure = read_sources(files).graph
    owlrl.DeductiveClosure(
        owlrl.OWLRL_Semantics, rdfs_closure=False, axiomatic_triples=False, datatype_axioms=False
    ).expand(closure)
    for sort in sorted(ont.sorts - {"http://www.w3.org/2002/07/owl#Thing"}):
        ours = {o for o in km.kb.engine.query("instance_of", platform, None, sort)}
        theirs = {
            str(s) for s in closure.subjects(RDF.type, URIRef(sort)) if str(s) in ont.individuals
        }
        assert {str(o[1]) for o in ours} == theirs, local_name(sort)
    rep = {str(r[1]): str(r[2]) for r in km.kb.engine.query("same_rep", platform, None, None)}
    for obj in sorted(ont.individuals):
        theirs = {str(o) for o in closure.objects(URIRef(obj), OWL.sameAs)} & ont.individuals
        assert {o for o in ont.individuals if rep[o] == rep[obj]} == theirs | {obj}, obj


@pytest.mark.parametrize("name", ["entailing", "platform1", "weather"])
def test_memberships_equal_owlrls_closure(tmp_path: Path, name: str) -> None:
    from dkreason import KnowledgeManager

    if name == "entailing":
        km = entailing(tmp_path)
        files = [tmp_path / "e.ttl"]
    else:
        files = (
            [SCENARIOS / "ontologies" / "platform1.owl"]
            if name == "platform1"
            else [SOSA / "weather.ttl"]
        )
        (tmp_path / "c.toml").write_text(
            f'[platforms.e]\nontology = "{files[0]}"\nreasoning = "owl-rl"\n'
        )
        km = KnowledgeManager.from_config(tmp_path / "c.toml")
    agrees_with_owlrl(km, files)


@pytest.mark.parametrize(  # owlrl, the oracle, writes sameAs out pairwise: kept small
    ("kind", "n"), [("same-as", 12), ("transitive", 30), ("functional", 12), ("subclass", 30)]
)
def test_large_closures_equal_owlrls_and_stay_per_same_as_class(
    tmp_path: Path, kind: str, n: int
) -> None:
    """Chains make OWL RL's closure grow with the square of their length (issue 27, defect
    5); the rules keep sameAs as classes and memberships per class, and still agree with
    owlrl.  The lengths that took minutes are measured in benchmarks/bench_owlrl.py."""
    from dkreason import KnowledgeManager
    from dkreason.workloads import owl_rl_world

    (tmp_path / "o.ttl").write_text(owl_rl_world(kind, n))
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.ttl"\nreasoning = "owl-rl"\n')
    km = KnowledgeManager.from_config(tmp_path / "c.toml")
    agrees_with_owlrl(km, [tmp_path / "o.ttl"])
    ont = km.kb.platform("p").ontology
    assert len(ont.entailed) <= 2 * n  # a pair per object at most, not a pair per two objects


def test_an_unresolved_import_on_the_cli_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dkreason.cli import main

    config = station(tmp_path)
    (tmp_path / "catalog-v001.xml").unlink()
    assert main(["match", "--config", str(config), "always (Reading[baro1] > 1)"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "owl:imports <http://www.w3.org/ns/ssn/>" in err


def test_the_weather_example_expands_over_sosa_sensors(capsys: pytest.CaptureFixture[str]) -> None:
    from dkreason.cli import main

    from .conftest import REPO

    assert (
        main(
            [
                "match",
                "--json",
                "--config",
                str(REPO / "examples" / "weather" / "station.toml"),
                "forall s in System: always (Reading[s] > 900)",
            ]
        )
        == 0
    )
    request = json.loads(capsys.readouterr().out)
    assert [(f["args"], [t["filter"] for t in f["topics"]]) for f in request["features"]] == [
        (["baro1"], [{"msg.id": 1}]),
        (["baro2"], [{"msg.id": 2}]),
    ]
