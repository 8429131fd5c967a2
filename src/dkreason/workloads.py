"""Seeded workloads written as ordinary OWL and SSL_T files, for the benchmarks, the tests and
anyone sizing a deployment: thesis chapter 7's evaluation worlds (section 7.2), and a fleet.

Chapter 7: every ontology has concepts A–E (B–E under A), the relations X (unary), Y (binary) and
Z (ternary) over A, and the individuals the formulas name: b1–b3 of B, d1–d3 of D, e1–e3 of E.
Further concepts are each a top concept or a subconcept of a randomly chosen earlier one;
further individuals are relevant (of B, like the formula's objects) or irrelevant (of another
concept).  Topic specifications: one relevant spec per feature of the formula, irrelevant ones
that differ from a relevant one in one argument, and further relevant ones for the same
features (as in the thesis, every spec names objects; topics over a sort are timed by
benchmarks/bench_match.py on the case-study scenarios).  `scale` multiplies every size.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass
from itertools import product
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rdflib import Graph, URIRef
    from rdflib.term import Node

NS = "http://example.org/ch7#"
NINE = [
    "X[b1]",
    "X[b2]",
    "X[b3]",
    "Y[b1, b1]",
    "Y[b1, b2]",
    "Y[b1, b3]",
    "Z[b1, b2, b1]",
    "Z[b1, b2, b2]",
    "Z[b1, b2, b3]",
]
QUANTIFIED = {
    3: "forall x in B (Z[x, d1, e1])",
    9: "forall x in B, y in D (Z[x, y, e1])",
    27: "forall x in B, y in D, z in E(Z[x, y, z])",
}


@dataclass(frozen=True)
class Workload:
    concepts: int  # in all, A–E included
    relevant: int  # individuals of B besides b1–b3 (d1–d3 and e1–e3 always exist)
    irrelevant: int  # individuals of other concepts
    relevant_specs: int  # besides one per feature of the formula
    irrelevant_specs: int
    features: list[str]  # ground features the relevant specs are made for
    seed: int = 7
    sort_share: float = 0.0  # of the further relevant specs, the share that read sorts


def nine() -> list[str]:
    return list(NINE)


def many(n: int) -> list[str]:
    """n distinct ground features over b1..bk (test case 3)."""
    k = 3
    while k + k * k + k**3 < n:
        k += 1
    b = [f"b{i}" for i in range(1, k + 1)]
    pool = (
        [f"X[{x}]" for x in b]
        + [f"Y[{x}, {y}]" for x, y in product(b, b)]
        + [f"Z[{x}, {y}, {z}]" for x, y, z in product(b, b, b)]
    )
    return pool[:n]


def expanded(n: int) -> list[str]:
    """The ground features a quantified formula of test case 4 expands to."""
    if n == 3:
        return [f"Z[b{i}, d1, e1]" for i in (1, 2, 3)]
    if n == 9:
        return [f"Z[b{i}, d{j}, e1]" for i in (1, 2, 3) for j in (1, 2, 3)]
    return [f"Z[b{i}, d{j}, e{k}]" for i in (1, 2, 3) for j in (1, 2, 3) for k in (1, 2, 3)]


def formula(features: list[str]) -> str:
    return " and ".join(features)


def write(w: Workload, folder: Path) -> Path:
    """Write ontology, specs and config into `folder`; return the config path."""
    rnd = random.Random(w.seed)
    folder.mkdir(parents=True, exist_ok=True)
    concepts = ["A", "B", "C", "D", "E"]
    parent: dict[str, str | None] = {"A": None, "B": "A", "C": "A", "D": "A", "E": "A"}
    for i in range(max(w.concepts - 5, 0)):
        name = f"K{i}"
        parent[name] = rnd.choice(concepts) if rnd.random() < 0.8 else None
        concepts.append(name)
    individuals = {f"{c}{i}": c.upper() for c in "bde" for i in (1, 2, 3)}
    for i in range(w.relevant):
        individuals[f"b{4 + i}"] = "B"
    quantified = _below("B", parent) | _below("D", parent) | _below("E", parent)
    others = [c for c in concepts if c != "A" and c not in quantified]  # B, D, E stay as named
    for i in range(w.irrelevant):
        individuals[f"o{i}"] = rnd.choice(others)
    (folder / "ch7.owl").write_text(_owl(parent, individuals), encoding="utf-8")

    specs = [_spec(f"rel{n}", f) for n, f in enumerate(w.features)]
    under_a = _below("A", parent)
    names = sorted(i for i, c in individuals.items() if c in under_a)  # fit X, Y, Z
    for n in range(w.irrelevant_specs):
        name, args = _parse(rnd.choice(w.features))
        k = rnd.randrange(len(args))
        args[k] = rnd.choice([x for x in names if x != args[k]])
        specs.append(_spec(f"irr{n}", f"{name}[{', '.join(args)}]"))
    sorted_specs = round(w.relevant_specs * w.sort_share)
    for n in range(w.relevant_specs):  # further topics for the formula's features
        specs.append(
            _spec(f"extra{n}", w.features[n % len(w.features)], over_sort=n < sorted_specs)
        )
    (folder / "ch7.sslt").write_text("\n".join(specs) + "\n", encoding="utf-8")
    config = folder / "ch7.toml"
    config.write_text(
        'local = "ch7"\n[platforms.ch7]\nontology = "ch7.owl"\nspecs = "ch7.sslt"\n',
        encoding="utf-8",
    )
    return config


def _below(root: str, parent: dict[str, str | None]) -> set[str]:
    """`root` and its subconcepts; `parent` lists parents before their children."""
    below = {root}
    for c, p in parent.items():
        if p in below:
            below.add(c)
    return below


def _parse(feature: str) -> tuple[str, list[str]]:
    name, rest = feature.split("[")
    return name, [a.strip() for a in rest.rstrip("]").split(",")]


def _spec(topic: str, feature: str, over_sort: bool = False) -> str:
    """A topic carrying `feature`; `over_sort`: its b-arguments read `some B` instead (every
    object of B, the formula's among them)."""
    name, args = _parse(feature)
    labels = [f"a{i}" for i in range(len(args))]
    sort_arg = [over_sort and a.startswith("b") for a in args]
    aliased = ", ".join(
        f"{'B' if s else a} as {lab}" for a, lab, s in zip(args, labels, sort_arg, strict=True)
    )
    ids = ", ".join(
        f"{'some ' if s else ''}{lab} = msg.id{i + 1}"
        for i, (lab, s) in enumerate(zip(labels, sort_arg, strict=True))
    )
    return f"topic {topic}:M contains {name}({aliased}) = msg.v for {ids}"


def _owl(parent: dict[str, str | None], individuals: dict[str, str]) -> str:
    out = [
        '<?xml version="1.0"?>',
        f'<rdf:RDF xmlns="{NS}" xml:base="{NS[:-1]}"',
        '  xmlns:owl="http://www.w3.org/2002/07/owl#"',
        '  xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"',
        '  xmlns:rdfs="http://www.w3.org/2000/01/rdf-schema#">',
        f'<owl:Ontology rdf:about="{NS[:-1]}"/>',
    ]
    for arg in ("arg1", "arg2", "arg3"):
        out.append(f'<owl:ObjectProperty rdf:about="{NS}{arg}"/>')
    for c in ("Relation", "UnaryRelation", "BinaryRelation", "TernaryRelation"):
        sup = "" if c == "Relation" else f'<rdfs:subClassOf rdf:resource="{NS}Relation"/>'
        out.append(f'<owl:Class rdf:about="{NS}{c}">{sup}</owl:Class>')
    for c, p in parent.items():
        sup = f'<rdfs:subClassOf rdf:resource="{NS}{p}"/>' if p else ""
        out.append(f'<owl:Class rdf:about="{NS}{c}">{sup}</owl:Class>')
    for name, kind, arity in (
        ("X", "UnaryRelation", 1),
        ("Y", "BinaryRelation", 2),
        ("Z", "TernaryRelation", 3),
    ):
        restrictions = "".join(
            f'<owl:Restriction><owl:onProperty rdf:resource="{NS}arg{i}"/>'
            f'<owl:allValuesFrom rdf:resource="{NS}A"/></owl:Restriction>'
            for i in range(1, arity + 1)
        )
        out.append(
            f'<owl:Class rdf:about="{NS}{name}"><rdfs:subClassOf><owl:Class>'
            f'<owl:intersectionOf rdf:parseType="Collection">'
            f'<rdf:Description rdf:about="{NS}{kind}"/>{restrictions}'
            f"</owl:intersectionOf></owl:Class></rdfs:subClassOf></owl:Class>"
        )
    for ind, cls in individuals.items():
        out.append(
            f'<owl:NamedIndividual rdf:about="{NS}{ind}">'
            f'<rdf:type rdf:resource="{NS}{cls}"/></owl:NamedIndividual>'
        )
    out.append("</rdf:RDF>")
    return "\n".join(out) + "\n"


# ---- the points of the thesis' test cases (tables 7.1-7.7) ----------------------------------


def _nine_setup(
    concepts: int, relevant: int, irrelevant: int, rel_specs: int, irr_specs: int
) -> tuple[Workload, str]:
    return Workload(concepts, relevant, irrelevant, rel_specs, irr_specs, nine()), formula(nine())


def _case_1_1(i: int, s: int) -> tuple[Workload, str]:
    return _nine_setup(25 * (i + 1) * s, 0, 200 * s - 9, 0, 11 * s)


def _case_1_2(i: int, s: int) -> tuple[Workload, str]:
    return _nine_setup(200 * s, 0, 25 * i * s, 0, 11 * s)


def _case_1_3(i: int, s: int) -> tuple[Workload, str]:
    return _nine_setup(200 * s, 25 * i * s, 0, 0, 11 * s)


def _case_2_1(i: int, s: int) -> tuple[Workload, str]:
    return _nine_setup(50 * s, 50 * s, 0, 0, 100 * i * s)


def _case_2_2(i: int, s: int) -> tuple[Workload, str]:
    return _nine_setup(50 * s, 50 * s, 0, 100 * i * s, 9 * s)


def _case_3(i: int, s: int) -> tuple[Workload, str]:
    features = many(10 * (i + 1))
    return Workload(50 * s, 51 * s - 3, 0, 50 * s - len(features), 0, features), formula(features)


def _case_4(i: int, s: int) -> tuple[Workload, str]:
    n = (3, 9, 27)[i // 2]
    text = QUANTIFIED[n] if i % 2 == 0 else formula(expanded(n))
    return Workload(50 * s, 0, 50 * s - 9, 0, 0, expanded(27)), text


Setup = Callable[[int, int], tuple[Workload, str]]  # (column, scale) -> workload and formula
SETUPS: dict[str, Setup] = {
    "1.1": _case_1_1,
    "1.2": _case_1_2,
    "1.3": _case_1_3,
    "2.1": _case_2_1,
    "2.2": _case_2_2,
    "3": _case_3,
    "4": _case_4,
}
COLUMNS = {"1.1": 8, "1.2": 9, "1.3": 9, "2.1": 6, "2.2": 6, "3": 5, "4": 6}  # each table's x


# ---- a fleet sharing one vocabulary (bench_join, bench_fleet) -----------------------------


FLEET = "http://example.org/join#"


def _turtle(sensors: list[int]) -> str:
    objects = "\n".join(f":s{k} a owl:NamedIndividual, :Sensor ; :id {k} ." for k in sensors)
    return f"""@prefix : <{FLEET}> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Sensor a owl:Class .
:Reading rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :UnaryRelation
    [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Sensor ] ) ] .
{objects}
"""


def fleet(folder: Path, nodes: int) -> None:
    """A fleet sharing one vocabulary (the same IRIs, no mapping files): platform m knows
    every sensor; platform pN knows its own sensor sN and carries its topic tN (configs
    monitor.toml and pN.toml)."""
    (folder / "m.ttl").write_text(_turtle(list(range(1, nodes + 1))))
    (folder / "monitor.toml").write_text(
        'local = "m"\n[platforms.m]\nontology = "m.ttl"\n'
        + "".join(f"[platforms.p{n}]\n" for n in range(1, nodes + 1))
    )
    for n in range(1, nodes + 1):
        (folder / f"p{n}.ttl").write_text(_turtle([n]))
        (folder / f"p{n}.sslt").write_text(
            f"topic t{n}:Reading contains Reading(s{n}) = msg.value for s{n} = msg.id\n"
        )
        (folder / f"p{n}.toml").write_text(
            f'[platforms.p{n}]\nontology = "p{n}.ttl"\nspecs = "p{n}.sslt"\n'
        )


# ---- hostile ontologies (tests/test_owl.py, bench_owl_memory, bench_owlrl) -------------------


HOSTILE = "http://example.org/hostile#"


def nested_owl(syntax: str, depth: int, axioms: int = 1) -> str:
    """An ontology of `axioms` axioms, each nesting `depth` class expressions: in OWL
    Functional Syntax ("ofn"), Manchester syntax with parentheses ("omn") or with a chain of
    restrictions and none ("omn-chain"), or OWL/XML ("owx")."""
    if syntax == "ofn":
        nested = "ObjectIntersectionOf(:B " * depth + ":C" + ")" * depth
        body = "".join(f"SubClassOf(:A{i} {nested})\n" for i in range(axioms))
        return f"Prefix(:=<{HOSTILE}>)\nOntology(<{HOSTILE}>\n{body})\n"
    if syntax.startswith("omn"):
        nested = (
            "p some " * depth + "B" if syntax == "omn-chain" else "(" * depth + "B" + ")" * depth
        )
        body = "".join(f"Class: A{i}\n    SubClassOf: {nested}\n" for i in range(axioms))
        return f"Prefix: : <{HOSTILE}>\nOntology: <{HOSTILE}>\nObjectProperty: p\nClass: B\n{body}"
    iri = f'<Class IRI="{HOSTILE}'
    nested = f'<ObjectIntersectionOf>{iri}B"/>' * depth + f'{iri}C"/>'
    nested += "</ObjectIntersectionOf>" * depth
    body = "".join(f'<SubClassOf>{iri}A{i}"/>{nested}</SubClassOf>\n' for i in range(axioms))
    return (
        f'<?xml version="1.0"?>\n<Ontology xmlns="http://www.w3.org/2002/07/owl#" '
        f'ontologyIRI="{HOSTILE}">\n{body}</Ontology>\n'
    )


def assertions_owl(syntax: str, n: int) -> str:
    """An ontology of `n` class assertions, in "ofn", "omn", "owx" or "turtle"."""
    if syntax == "ofn":
        body = "".join(f"ClassAssertion(:C :i{i})\n" for i in range(n))
        return f"Prefix(:=<{HOSTILE}>)\nOntology(<{HOSTILE}>\nDeclaration(Class(:C))\n{body})\n"
    if syntax == "omn":
        body = "".join(f"Individual: i{i}\n  Types: C\n" for i in range(n))
        return f"Prefix: : <{HOSTILE}>\nOntology: <{HOSTILE}>\nClass: C\n{body}"
    if syntax == "owx":
        body = "".join(
            f'<ClassAssertion><Class IRI="{HOSTILE}C"/><NamedIndividual IRI="{HOSTILE}i{i}"/>'
            "</ClassAssertion>\n"
            for i in range(n)
        )
        return (
            f'<?xml version="1.0"?>\n<Ontology xmlns="http://www.w3.org/2002/07/owl#" '
            f'ontologyIRI="{HOSTILE}">\n{body}</Ontology>\n'
        )
    return f"@prefix : <{HOSTILE}> .\n" + "".join(f":i{i} a :C .\n" for i in range(n))


_RL_HEAD = f"""@prefix : <{HOSTILE}> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Robot a owl:Class .
:Battery rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :UnaryRelation
    [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
:near a owl:ObjectProperty, owl:TransitiveProperty ; rdfs:domain :Robot .
:has a owl:ObjectProperty, owl:FunctionalProperty .
"""


def owl_rl_world(kind: str, n: int) -> str:
    """Turtle in which OWL RL's closure is large for its size: a sameAs chain of `n` objects,
    each of a class of its own under Robot ("same-as"); a transitive property along `n` objects
    ("transitive"); a functional property with `n` values ("functional"); a subClassOf chain
    `n` deep with an object in each class ("subclass")."""
    if kind == "subclass":
        body = "".join(
            f":C{i} a owl:Class ; rdfs:subClassOf :{f'C{i + 1}' if i + 1 < n else 'Robot'} .\n"
            f":o{i} a owl:NamedIndividual, :C{i} .\n"
            for i in range(n)
        )
    elif kind == "same-as":
        body = "".join(
            f":K{i} a owl:Class ; rdfs:subClassOf :Robot .\n:o{i} a owl:NamedIndividual, :K{i}"
            + (f" ; owl:sameAs :o{i + 1} .\n" if i + 1 < n else " .\n")
            for i in range(n)
        )
    elif kind == "transitive":
        body = "".join(
            f":o{i} a owl:NamedIndividual" + (f" ; :near :o{i + 1} .\n" if i + 1 < n else " .\n")
            for i in range(n)
        )
    else:
        body = ":hub a owl:NamedIndividual .\n" + "".join(
            f":o{i} a owl:NamedIndividual .\n:hub :has :o{i} .\n" for i in range(n)
        )
    return _RL_HEAD + body


def _class_pattern(path: Path) -> tuple[Graph, list[tuple[URIRef, Node, int, dict[int, Node]]]]:
    """The ontology at `path` parsed, and its unary and binary feature classes: each with the
    told superclass that makes it one (UnaryRelation/BinaryRelation ⊓ ∀argN.S), its arity and
    its fillers by argument (ternary features are left out: both styles keep them)."""
    import re

    from rdflib import BNode, Graph, URIRef
    from rdflib.collection import Collection
    from rdflib.namespace import OWL, RDFS

    graph = Graph()
    graph.parse(path)
    arities = {"UnaryRelation": 1, "BinaryRelation": 2}
    found = []
    for cls, sup in list(graph.subject_objects(RDFS.subClassOf)):
        parts_at = graph.value(sup, OWL.intersectionOf) if isinstance(sup, BNode) else None
        if not isinstance(cls, URIRef) or parts_at is None:
            continue
        parts = list(Collection(graph, parts_at))
        arity = next(
            (arities[str(p).split("#")[-1]] for p in parts if str(p).split("#")[-1] in arities), 0
        )
        if arity:
            fillers = {
                int(m.group(1)): graph.value(part, OWL.allValuesFrom)
                for part in parts
                if (m := re.search(r"arg([12])$", str(graph.value(part, OWL.onProperty))))
            }
            found.append((cls, sup, arity, {i: f for i, f in fillers.items() if f is not None}))
    return graph, found


def property_style(path: Path) -> str:
    """The ontology at `path` (class pattern) rewritten as its properties would say it, as
    Turtle: a unary feature becomes an owl:DatatypeProperty with the rdfs:domain of its arg1,
    a binary one an owl:ObjectProperty with a domain and a range, owl:equivalentClass between
    features owl:equivalentProperty; ternary features stay feature classes (properties relate
    two things), so the result mixes both styles.  `adapters = ["properties"]` reads it back
    into the same features (rules/adapters/properties.dl)."""
    from rdflib.namespace import OWL, RDF, RDFS

    graph, found = _class_pattern(path)
    for cls, sup, arity, fillers in found:
        graph.remove((cls, RDFS.subClassOf, sup))
        graph.remove((cls, RDF.type, OWL.Class))
        graph.add((cls, RDF.type, OWL.DatatypeProperty if arity == 1 else OWL.ObjectProperty))
        graph.add((cls, RDFS.domain, fillers.get(1, OWL.Thing)))
        if arity == 2:
            graph.add((cls, RDFS.range, fillers.get(2, OWL.Thing)))
    features = {cls for cls, *_ in found}
    for a, b in list(graph.subject_objects(OWL.equivalentClass)):
        if a in features and b in features:
            graph.remove((a, OWL.equivalentClass, b))
            graph.add((a, OWL.equivalentProperty, b))
    return str(graph.serialize(format="turtle"))


def sosa_style(path: Path) -> str:
    """The ontology at `path` (class pattern) rewritten in W3C SOSA/SSN's terms, as Turtle: a
    unary feature becomes a class of observable properties tied to its sort, C ⊑
    sosa:ObservableProperty ⊓ ∀ssn:isPropertyOf.S; binary and ternary features stay feature
    classes (an observable property is of one thing), so the result mixes both styles.
    `adapters = ["sosa"]` reads it back into the same features (rules/adapters/sosa.dl)."""
    from rdflib import BNode, Namespace
    from rdflib.namespace import OWL, RDF, RDFS

    sosa, ssn = Namespace("http://www.w3.org/ns/sosa/"), Namespace("http://www.w3.org/ns/ssn/")
    graph, found = _class_pattern(path)
    graph.bind("sosa", sosa)
    graph.bind("ssn", ssn)
    for cls, sup, _, fillers in (f for f in found if f[2] == 1):
        tie = BNode()
        graph.remove((cls, RDFS.subClassOf, sup))
        graph.add((cls, RDFS.subClassOf, sosa.ObservableProperty))
        graph.add((cls, RDFS.subClassOf, tie))
        graph.add((tie, RDF.type, OWL.Restriction))
        graph.add((tie, OWL.onProperty, ssn.isPropertyOf))
        graph.add((tie, OWL.allValuesFrom, fillers.get(1, OWL.Thing)))
    return str(graph.serialize(format="turtle"))
