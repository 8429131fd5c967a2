"""The OWL 2 RL rules that type objects or relate them, over a graph's triples."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from typing import Any

from rdflib import Namespace, URIRef

OWL = Namespace("http://www.w3.org/2002/07/owl#")
RDF = Namespace("http://www.w3.org/1999/02/22-rdf-syntax-ns#")
RDFS = Namespace("http://www.w3.org/2000/01/rdf-schema#")
TYPE, SAME, THING = RDF.type, OWL.sameAs, OWL.Thing

Triple = tuple[Any, Any, Any]


def closure(triples: Iterable[Triple]) -> set[Triple]:
    """The fixpoint of the OWL 2 RL rules on assertions (tables 4-6 of the OWL 2 RL profile:
    eq-sym/trans, prp-dom/rng/fp/ifp/symp/trp/spo1/spo2/eqp/inv, cls-int1/int2/uni/svf1/svf2/
    avf/hv1/hv2, cax-sco/eqc), with the schema closed as far as those rules need."""
    facts: set[Triple] = set(triples)
    while True:
        new = _step(facts) - facts
        if not new:
            return facts
        facts |= new


def _lists(facts: set[Triple]) -> dict[Any, list[Any]]:
    first = {s: o for s, p, o in facts if p == RDF.first}
    rest = {s: o for s, p, o in facts if p == RDF.rest}
    out = {}
    for head in first:
        items, node, seen = [], head, set()
        while node in first and node not in seen:
            seen.add(node)
            items.append(first[node])
            node = rest.get(node)
        out[head] = items
    return out


def _step(facts: set[Triple]) -> set[Triple]:
    by_p: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
    for s, p, o in facts:
        by_p[p].append((s, o))
    types: dict[Any, set[Any]] = defaultdict(set)  # object → classes
    members: dict[Any, set[Any]] = defaultdict(set)  # class → objects
    for s, o in by_p[TYPE]:
        types[s].add(o)
        members[o].add(s)
    lists = _lists(facts)
    out: set[Triple] = set()
    add = out.add

    def typed(p: URIRef) -> list[Any]:
        return list(members.get(p, ()))

    # eq-sym, eq-trans
    same = by_p[SAME]
    partners: dict[Any, set[Any]] = defaultdict(set)
    for x, y in same:
        add((y, SAME, x))
        partners[x].add(y)
    for x, y in same:
        for z in partners.get(y, ()):
            if z != x:
                add((x, SAME, z))
    # eq-rep-s/o for types: a sameAs partner shares the classes
    for x, y in same:
        for c in types.get(x, ()):
            add((y, TYPE, c))
    # prp-dom, prp-rng
    for p, c in by_p[RDFS.domain]:
        for x, _ in by_p.get(p, ()):
            add((x, TYPE, c))
    for p, c in by_p[RDFS.range]:
        for _, y in by_p.get(p, ()):
            add((y, TYPE, c))
    # prp-fp, prp-ifp: one value per subject (per object, read backwards)
    for p in typed(OWL.FunctionalProperty):
        _single(by_p.get(p, ()), add)
    for p in typed(OWL.InverseFunctionalProperty):
        _single([(y, x) for x, y in by_p.get(p, ())], add)
    # prp-symp, prp-trp
    for p in typed(OWL.SymmetricProperty):
        for x, y in by_p.get(p, ()):
            add((y, p, x))
    for p in typed(OWL.TransitiveProperty):
        succ: dict[Any, set[Any]] = defaultdict(set)
        for x, y in by_p.get(p, ()):
            succ[x].add(y)
        for x, y in by_p.get(p, ()):
            for z in succ.get(y, ()):
                add((x, p, z))
    # prp-spo1, prp-eqp1/2, prp-inv1/2
    for p1, p2 in by_p[RDFS.subPropertyOf]:
        for x, y in by_p.get(p1, ()):
            add((x, p2, y))
    for p1, p2 in by_p[OWL.equivalentProperty]:
        for x, y in by_p.get(p1, ()):
            add((x, p2, y))
        for x, y in by_p.get(p2, ()):
            add((x, p1, y))
    for p1, p2 in by_p[OWL.inverseOf]:
        for x, y in by_p.get(p1, ()):
            add((y, p2, x))
        for x, y in by_p.get(p2, ()):
            add((y, p1, x))
    # prp-spo2: property chains
    for p, head in by_p[OWL.propertyChainAxiom]:
        chain = lists.get(head, [])
        if not chain:
            continue
        ends = {x: {x} for x, _ in by_p.get(chain[0], ())}
        for step in chain:
            succ = defaultdict(set)
            for x, y in by_p.get(step, ()):
                succ[x].add(y)
            ends = {x: {z for y in ys for z in succ.get(y, ())} for x, ys in ends.items()}
        for x, zs in ends.items():
            for z in zs:
                add((x, p, z))
    # cls-int1, cls-int2, cls-uni
    for c, head in by_p[OWL.intersectionOf]:
        parts = lists.get(head, [])
        if parts:
            for y in set.intersection(*(members.get(part, set()) for part in parts)):
                add((y, TYPE, c))
        for y in members.get(c, ()):
            for part in parts:
                add((y, TYPE, part))
    for c, head in by_p[OWL.unionOf]:
        for part in lists.get(head, []):
            for y in members.get(part, ()):
                add((y, TYPE, c))
    # restrictions: cls-svf1/2, cls-avf, cls-hv1/2
    on = dict(by_p[OWL.onProperty])
    for x, y in by_p[OWL.someValuesFrom]:
        p = on.get(x)
        for u, v in by_p.get(p, ()):
            if y == THING or y in types.get(v, ()):
                add((u, TYPE, x))
    for x, y in by_p[OWL.allValuesFrom]:
        p = on.get(x)
        for u, v in by_p.get(p, ()):
            if x in types.get(u, ()):
                add((v, TYPE, y))
    for x, y in by_p[OWL.hasValue]:
        p = on.get(x)
        for u in members.get(x, ()):
            add((u, p, y))
        for u, v in by_p.get(p, ()):
            if v == y:
                add((u, TYPE, x))
    # cax-sco, cax-eqc1/2
    for c1, c2 in by_p[RDFS.subClassOf]:
        for x in members.get(c1, ()):
            add((x, TYPE, c2))
    for c1, c2 in by_p[OWL.equivalentClass]:
        for x in members.get(c1, ()):
            add((x, TYPE, c2))
        for x in members.get(c2, ()):
            add((x, TYPE, c1))
    return out


def _single(pairs: Iterable[tuple[Any, Any]], add: Any) -> None:
    """Each key has one value: the values found for a key are sameAs each other."""
    seen: dict[Any, Any] = {}
    for key, value in pairs:
        if key in seen and seen[key] != value:
            add((seen[key], SAME, value))
        seen.setdefault(key, value)
