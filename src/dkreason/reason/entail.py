"""OWL 2 RL entailments of class membership and sameAs (`reasoning = "owl-rl"`).

Real ontologies type their objects through property domains and ranges, restrictions and
intersections, and the thesis ran Pellet for that.  The closure is the OWL 2 RL rules that
type or relate objects (owlrl_rules.py: the profile's eq-, prp-, cls- and cax- rules),
computed once per load and cached with the platform; only what it adds about named objects is
kept: their classes and sameAs partners.  Feature signatures stay as told (an OWL closure
would give equivalent features each other's signatures, thesis 6.1), and a membership the
told subclass axioms already give is left to the rules.  Each entailed pair is kept with the
told axiom it follows from, for explanations.  owlrl, the full OWL 2 RL reasoner, is the
oracle in the tests (the same memberships on every test ontology); it takes 20-30× what
rdflib needs to parse the files, these rules a fraction of it (benchmarks/bench_owlrl.py).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import replace
from typing import Any

from ..model import Ontology
from ..names import local_name
from .owlrl_rules import Closure, closure


def entail(graph: Any, told: Ontology) -> Ontology:
    """`told` with the memberships and sameAs pairs OWL 2 RL entails from `graph`.

    Both are kept per sameAs class (the knowledge base gives a class's memberships to all its
    members): a class's entailed sorts once, on the member each was entailed for, and just
    enough entailed pairs to join what told sameAs leaves apart, never all n² pairs."""
    from rdflib import URIRef

    found = closure(graph)
    supers = _told_supers(told)
    objects, sorts = told.individuals, told.sorts
    told_sorts: dict[str, set[str]] = defaultdict(set)
    for obj, cls in told.types:
        told_sorts[obj].add(cls)
    told_class = _classes(told.same_as)
    types: dict[tuple[str, str], str] = {}
    same: dict[tuple[str, str], str] = {}
    for rep in found.types.keys() | found.groups.keys():
        classes = found.types.get(rep, set())
        members = sorted(
            str(m) for m in found.members(rep) if isinstance(m, URIRef) and str(m) in objects
        )
        if not members:
            continue
        joined = {told_class.get(members[0], members[0])}
        for m in members[1:]:  # one pair per told class of sameAs the first one's is apart from
            if told_class.get(m, m) not in joined:
                joined.add(told_class.get(m, m))
                same[(members[0], m)] = (
                    f"entailed by OWL RL from {_why_same(graph, URIRef(members[0]), URIRef(m))}"
                )
        held = {str(c) for c in classes} & sorts
        given = set().union(*(told_sorts[m] for m in members))
        for cls in held - given:  # the most specific only: the rules climb the told hierarchy
            if any(cls in supers[other] and other not in supers[cls] for other in held):
                continue
            origin = str(found.origin.get((rep, URIRef(cls)), ""))
            obj = origin if origin in members else members[0]
            types[(obj, cls)] = "entailed by OWL RL from " + _why_type(
                graph, found, URIRef(obj), URIRef(cls)
            )
    return replace(
        told,
        types=(*told.types, *sorted(types)),
        same_as=(*told.same_as, *sorted(same)),
        entailed=types | same,
    )


def _classes(pairs: tuple[tuple[str, str], ...]) -> dict[str, str]:
    """Each object in a told sameAs pair → a representative of its told sameAs class."""
    parent: dict[str, str] = {}

    def root(x: str) -> str:
        top = x
        while parent.get(top, top) != top:
            top = parent[top]
        while x != top:
            parent[x], x = top, parent[x]
        return top

    for a, b in pairs:
        parent[root(a)] = root(b)
    return {x: root(x) for x in parent}


def _told_supers(told: Ontology) -> dict[str, set[str]]:
    """Each class's superclasses by told subClassOf and equivalentClass (what rules derive)."""
    up: dict[str, set[str]] = defaultdict(set)
    for a, b in told.subclass_of:
        up[a].add(b)
    for a, b in told.equivalent:
        up[a].add(b)
        up[b].add(a)
    out: dict[str, set[str]] = defaultdict(set)
    for start in list(up):
        seen: set[str] = set()
        todo = [start]
        while todo:
            for nxt in up[todo.pop()] - seen:
                seen.add(nxt)
                todo.append(nxt)
        out[start] = seen
    return out


def _name(node: Any) -> str:
    return local_name(str(node))


def _why_type(graph: Any, found: Closure, s: Any, c: Any) -> str:
    """The told axiom a membership s : c follows from, in a few words (the first found of the
    OWL 2 RL rules that type an object: domain, range, hasValue, someValuesFrom,
    intersection), else the rule set itself."""
    from rdflib import BNode
    from rdflib.collection import Collection
    from rdflib.namespace import OWL, RDFS

    for p, subjects in found.out.items():  # s's assertions, told or entailed (chains)
        if s in subjects:
            for d in graph.objects(p, RDFS.domain):
                if d == c:
                    return f"{_name(p)} rdfs:domain {_name(c)}"
    for p, objects in found.into.items():
        if s in objects:
            for r in graph.objects(p, RDFS.range):
                if r == c:
                    return f"{_name(p)} rdfs:range {_name(c)}"
    for restriction in graph.objects(c, OWL.equivalentClass):
        if not isinstance(restriction, BNode):
            continue
        prop = graph.value(restriction, OWL.onProperty)
        value = graph.value(restriction, OWL.hasValue)
        if prop is not None and value is not None:
            return f"{_name(c)} ≡ {_name(prop)} value {_name(value)}"
        some = graph.value(restriction, OWL.someValuesFrom)
        if prop is not None and some is not None:
            return f"{_name(c)} ≡ {_name(prop)} some {_name(some)}"
        parts = graph.value(restriction, OWL.intersectionOf)
        if parts is not None:
            shown = " ⊓ ".join(_name(x) for x in Collection(graph, parts))
            return f"{_name(c)} ≡ {shown}"
    return f"the OWL 2 RL rules ({_name(s)} : {_name(c)})"


def _why_same(graph: Any, a: Any, b: Any) -> str:
    from rdflib.namespace import OWL, RDF

    for p, v in graph.predicate_objects(a):
        if (b, p, v) in graph and (p, RDF.type, OWL.InverseFunctionalProperty) in graph:
            return f"{_name(p)} is inverse functional ({_name(a)} and {_name(b)} share it)"
    for v, p in graph.subject_predicates(a):
        if (v, p, b) in graph and (p, RDF.type, OWL.FunctionalProperty) in graph:
            return f"{_name(p)} is functional ({_name(v)} has both)"
    return f"the OWL 2 RL rules ({_name(a)} = {_name(b)})"
