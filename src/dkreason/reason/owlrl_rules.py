"""The OWL 2 RL rules that type objects or relate them, over a graph's triples, semi-naive.

Tables 4-6 of the OWL 2 RL profile: eq-sym/trans/rep (for memberships), prp-dom/rng/fp/ifp/
symp/trp/spo1/spo2/eqp/inv, cls-int1/int2/uni/svf1/svf2/avf/hv1/hv2, cax-sco/eqc.  Each fact is
joined once, when it is new, with what is known by then (a worklist), so the closure costs what
it derives: recomputing every rule over every fact each round took minutes on a sameAs chain of
300 objects.  Two relations are kept in closed form, never as pairs: sameAs as classes
(union-find) whose members share their memberships, and a transitive property, whose new edge
at once joins every object before it to every object after it.  The schema the rules read
(domains, ranges, hierarchies, restrictions, lists) is the told one; a property characteristic
(functional, transitive, …) may also be entailed.
"""

from __future__ import annotations

from collections import defaultdict, deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from rdflib import Namespace

OWL = Namespace("http://www.w3.org/2002/07/owl#")
RDF = Namespace("http://www.w3.org/1999/02/22-rdf-syntax-ns#")
RDFS = Namespace("http://www.w3.org/2000/01/rdf-schema#")
TYPE, SAME, THING = RDF.type, OWL.sameAs, OWL.Thing
FUNCTIONAL, INVERSE_FUNCTIONAL = OWL.FunctionalProperty, OWL.InverseFunctionalProperty
SYMMETRIC, TRANSITIVE = OWL.SymmetricProperty, OWL.TransitiveProperty

Triple = tuple[Any, Any, Any]
Index = dict[Any, dict[Any, set[Any]]]  # property → node → nodes

CHARACTERISTICS = (FUNCTIONAL, INVERSE_FUNCTIONAL, SYMMETRIC, TRANSITIVE)


@dataclass(frozen=True, slots=True)
class Closure:
    """What the rules entail.  `types`: each sameAs class, by its representative (a node in
    no class of two is its own), → the classes it belongs to, and `origin` the member each was
    first entailed for; `groups`: a representative → its class, if of two or more;
    `out`/`into`: property → subject → objects, and back (told and entailed)."""

    groups: dict[Any, list[Any]]
    types: dict[Any, set[Any]]
    origin: dict[tuple[Any, Any], Any]
    out: Index
    into: Index

    def members(self, rep: Any) -> list[Any]:
        return self.groups.get(rep, [rep])


def closure(triples: Iterable[Triple]) -> Closure:
    """The fixpoint of the rules on the told `triples`."""
    canon: dict[Any, Any] = {}  # one object per term: a lookup that finds it compares identity,
    intern = canon.setdefault  # not rdflib's __eq__ (a Python call each)
    rules = _Rules([(intern(s, s), intern(p, p), intern(o, o)) for s, p, o in triples], canon)
    rules.run()
    return rules.result()


def _lists(triples: list[Triple]) -> dict[Any, list[Any]]:
    first_p, rest_p = RDF.first, RDF.rest  # an attribute of a Namespace is made each time
    first = {s: o for s, p, o in triples if p == first_p}
    rest = {s: o for s, p, o in triples if p == rest_p}
    out = {}
    for head in first:
        items, node, seen = [], head, set()
        while node in first and node not in seen:
            seen.add(node)
            items.append(first[node])
            node = rest.get(node)
        out[head] = items
    return out


class _Rules:
    """The schema, read once, and the facts derived so far, with the worklist of new ones."""

    def __init__(self, triples: list[Triple], canon: dict[Any, Any]) -> None:
        lists = _lists(triples)
        pairs: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        for s, p, o in triples:
            pairs[p].append((s, o))

        def table(predicate: Any, both: bool = False) -> dict[Any, list[Any]]:
            out: dict[Any, list[Any]] = defaultdict(list)
            for s, o in pairs[predicate]:
                out[s].append(o)
                if both:
                    out[o].append(s)
            return out

        self.domain, self.range = table(RDFS.domain), table(RDFS.range)
        self.up = table(RDFS.subClassOf)  # cax-sco, and cax-eqc both ways
        for c, d in pairs[OWL.equivalentClass]:
            self.up[c].append(d)
            self.up[d].append(c)
        self.super_props = table(RDFS.subPropertyOf)  # prp-spo1, prp-eqp both ways
        for p, q in pairs[OWL.equivalentProperty]:
            self.super_props[p].append(q)
            self.super_props[q].append(p)
        self.inverse = table(OWL.inverseOf, both=True)
        self.parts = {c: lists.get(h, []) for c, h in pairs[OWL.intersectionOf]}
        self.in_intersections: dict[Any, list[Any]] = defaultdict(list)
        for c, parts in self.parts.items():
            for part in parts:
                self.in_intersections[part].append(c)
        self.in_unions: dict[Any, list[Any]] = defaultdict(list)
        for c, head in pairs[OWL.unionOf]:
            for part in lists.get(head, []):
                self.in_unions[part].append(c)
        on = dict(pairs[OWL.onProperty])

        def restrictions(predicate: Any) -> list[tuple[Any, Any, Any]]:
            """(restriction, its property, its filler or value)"""
            return [(x, on[x], y) for x, y in pairs[predicate] if x in on]

        # restrictions by property (read by a new assertion) and by what a new membership is
        self.some: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        self.filled_by: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        for x, p, y in restrictions(OWL.someValuesFrom):
            self.some[p].append((x, y))
            self.filled_by[y].append((x, p))
        self.all: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        self.all_of: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        for x, p, y in restrictions(OWL.allValuesFrom):
            self.all[p].append((x, y))
            self.all_of[x].append((p, y))
        self.value: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        self.value_of: dict[Any, list[tuple[Any, Any]]] = defaultdict(list)
        for x, p, y in restrictions(OWL.hasValue):
            self.value[p].append((x, y))
            self.value_of[x].append((p, y))
        self.chains: dict[Any, list[tuple[Any, list[Any], int]]] = defaultdict(list)
        for p, head in pairs[OWL.propertyChainAxiom]:
            chain = lists.get(head, [])
            for k, step in enumerate(chain):
                self.chains[step].append((p, chain, k))
        self.thing, self.is_transitive = canon.get(THING, THING), canon.get(TRANSITIVE, TRANSITIVE)
        self.kinds: dict[Any, set[Any]] = {canon.get(c, c): set() for c in CHARACTERISTICS}
        self.plans: dict[Any, tuple[Any, ...]] = {}
        self.functional = self.kinds[canon.get(FUNCTIONAL, FUNCTIONAL)]
        self.inverse_functional = self.kinds[canon.get(INVERSE_FUNCTIONAL, INVERSE_FUNCTIONAL)]
        self.symmetric = self.kinds[canon.get(SYMMETRIC, SYMMETRIC)]
        self.transitive = self.kinds[self.is_transitive]

        self.parent: dict[Any, Any] = {}
        self.groups: dict[Any, list[Any]] = {}
        self.types: dict[Any, set[Any]] = defaultdict(set)
        self.origin: dict[tuple[Any, Any], Any] = {}
        self.out: Index = defaultdict(lambda: defaultdict(set))
        self.into: Index = defaultdict(lambda: defaultdict(set))
        self.todo: deque[tuple[str, Any, Any, Any]] = deque()
        is_type, is_same = canon.get(TYPE), canon.get(SAME)
        for s, p, o in triples:
            if p is is_type:
                self.todo.append(("type", s, o, None))
            elif p is is_same:
                self.todo.append(("same", s, o, None))
            else:
                self.todo.append(("prop", s, p, o))

    def run(self) -> None:
        todo = self.todo
        while todo:
            kind, a, b, c = todo.popleft()
            if kind == "type":
                self.type(a, b)
            elif kind == "prop":
                self.prop(a, b, c)
            else:
                self.same(a, b)

    def result(self) -> Closure:
        return Closure(self.groups, dict(self.types), self.origin, self.out, self.into)

    def find(self, x: Any) -> Any:
        parent = self.parent
        root = x
        while root in parent:
            root = parent[root]
        while x in parent and parent[x] is not root:
            parent[x], x = root, parent[x]
        return root

    # ---- memberships ---------------------------------------------------------------------------

    def type(self, x: Any, c: Any) -> None:
        r = self.find(x)
        held = self.types[r]
        if c not in held:
            held.add(c)
            self.origin.setdefault((r, c), x)
            self.typed(r, c, self.groups.get(r, [r]))

    def typed(self, r: Any, c: Any, members: list[Any]) -> None:
        """c now holds for `members` of r's sameAs class: the rules that read memberships."""
        push, held = self.todo.append, self.types[r]
        for d in self.up.get(c, ()):  # cax-sco, cax-eqc
            push(("type", r, d, None))
        for part in self.parts.get(c, ()):  # cls-int2
            push(("type", r, part, None))
        for whole in self.in_intersections.get(c, ()):  # cls-int1
            if all(part in held for part in self.parts[whole]):
                push(("type", r, whole, None))
        for whole in self.in_unions.get(c, ()):  # cls-uni
            push(("type", r, whole, None))
        for p, y in self.all_of.get(c, ()):  # cls-avf
            for m in members:
                for v in self.out[p].get(m, ()):
                    push(("type", v, y, None))
        for p, v in self.value_of.get(c, ()):  # cls-hv1
            for m in members:
                push(("prop", m, p, v))
        for x, p in self.filled_by.get(c, ()):  # cls-svf1, its filler's side
            for v in members:
                for u in self.into[p].get(v, ()):
                    push(("type", u, x, None))
        if c in self.kinds:
            for p in members:
                self.characteristic(p, c)

    def characteristic(self, p: Any, kind: Any) -> None:
        """p has a characteristic (told or entailed): its assertions so far are read again."""
        if p in self.kinds[kind]:
            return
        self.kinds[kind].add(p)
        edges = [(x, y) for x, ys in self.out[p].items() for y in ys]
        if kind is self.is_transitive:  # closed again from its edges
            self.out[p].clear()
            self.into[p].clear()
            for x, y in edges:
                self.todo.append(("prop", x, p, y))
        else:
            for x, y in edges:
                self.fired(x, p, y)

    # ---- property assertions -------------------------------------------------------------------

    def prop(self, x: Any, p: Any, y: Any) -> None:
        if y in self.out[p].get(x, ()):
            return
        if p not in self.transitive:
            self.add(x, p, y)
            self.fired(x, p, y)
            return
        # prp-trp, in closed form: everything before x now reaches everything after y
        before, after = [x, *self.into[p].get(x, ())], [y, *self.out[p].get(y, ())]
        for a in before:
            reached = self.out[p][a]
            for b in after:
                if b not in reached:
                    self.add(a, p, b)
                    self.fired(a, p, b)

    def add(self, x: Any, p: Any, y: Any) -> None:
        self.out[p][x].add(y)
        self.into[p][y].add(x)

    def fired(self, x: Any, p: Any, y: Any) -> None:
        """(x p y) is new: the rules that read property assertions."""
        push = self.todo.append
        if p in self.functional or p in self.inverse_functional:
            self.single(x, p, y)
        if p in self.symmetric:  # prp-symp
            push(("prop", y, p, x))
        plan = self.plans.get(p)
        if plan is None:  # the schema is the told one: what reads p is known once p is
            plan = self.plans[p] = tuple(
                table.get(p, ())
                for table in (
                    self.domain,
                    self.range,
                    self.super_props,
                    self.inverse,
                    self.some,
                    self.all,
                    self.value,
                    self.chains,
                )
            )
        domains, ranges, supers, inverses, some, every, value, chains = plan
        for c in domains:  # prp-dom
            push(("type", x, c, None))
        for c in ranges:  # prp-rng
            push(("type", y, c, None))
        for q in supers:  # prp-spo1, prp-eqp1/2
            push(("prop", x, q, y))
        for q in inverses:  # prp-inv1/2
            push(("prop", y, q, x))
        for r, filler in some:  # cls-svf1/2
            if filler is self.thing or filler in self.types.get(self.find(y), ()):
                push(("type", x, r, None))
        for r, filler in every:  # cls-avf
            if r in self.types.get(self.find(x), ()):
                push(("type", y, filler, None))
        for r, v in value:  # cls-hv2
            if v is y:
                push(("type", x, r, None))
        for whole, chain, k in chains:  # prp-spo2
            starts, ends = {x}, {y}
            for step in reversed(chain[:k]):
                starts = {w for s in starts for w in self.into[step].get(s, ())}
            for step in chain[k + 1 :]:
                ends = {z for e in ends for z in self.out[step].get(e, ())}
            for w in starts:
                for z in ends:
                    push(("prop", w, whole, z))

    def single(self, x: Any, p: Any, y: Any) -> None:
        """prp-fp, prp-ifp: a second value of a functional property is the first one (each new
        value joins one other, so all end in one class)."""
        if p in self.functional:
            other = next((v for v in self.out[p][x] if v != y), None)
            if other is not None:
                self.todo.append(("same", y, other, None))
        if p in self.inverse_functional:
            other = next((u for u in self.into[p][y] if u != x), None)
            if other is not None:
                self.todo.append(("same", x, other, None))

    # ---- sameAs --------------------------------------------------------------------------------

    def same(self, x: Any, y: Any) -> None:
        """eq-sym/trans: one class; eq-rep: each side now has the other's memberships."""
        rx, ry = self.find(x), self.find(y)
        if rx is ry:
            return
        mx, my = self.groups.pop(rx, [rx]), self.groups.pop(ry, [ry])
        if len(mx) < len(my):  # the smaller class joins the larger: n log n in all
            rx, ry, mx, my = ry, rx, my, mx
        self.parent[ry] = rx
        tx, ty = self.types[rx], self.types.pop(ry, set())
        new_x, new_y = ty - tx, tx - ty
        tx |= ty
        for c in ty:
            self.origin.setdefault((rx, c), self.origin.pop((ry, c), y))
        for c in new_x:
            self.typed(rx, c, mx)
        for c in new_y:
            self.typed(rx, c, my)
        mx.extend(my)
        self.groups[rx] = mx
