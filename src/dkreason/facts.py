"""Model → Datalog facts.  Every relation the rules read is produced here, keyed by platform.

Entities are IRIs (strings); feature arguments are 1-based positions; topic arguments carry
their kind ('object', 'some', 'every') and id field ('' for an implicit object).
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

from .errors import DkError
from .model import ArgKind, Ontology
from .names import local_name
from .policy.syntax import Row

THING = "http://www.w3.org/2002/07/owl#Thing"
_TRAILING_DIGITS = re.compile(r"(?<![0-9])([0-9]{1,18})$")  # longer: no id, not a hang

Facts = dict[str, list[Row]]

# Constants the rules join against: argument positions of the ternary-padded tuples, and the
# topic argument kinds that name a sort.
STATIC: Facts = {"position": [(1,), (2,), (3,)], "sort_kind": [("some",), ("every",)]}


@dataclass(frozen=True, slots=True)
class ResolvedArg:
    kind: ArgKind
    iri: str
    id_field: str  # '' for an implicit object


@dataclass(frozen=True, slots=True)
class ResolvedFeature:
    iri: str
    field: str
    args: tuple[ResolvedArg, ...]


@dataclass(frozen=True, slots=True)
class ResolvedSpec:
    """A topic spec with every name resolved to an IRI of its platform."""

    name: str
    msgtype: str
    features: tuple[ResolvedFeature, ...]
    entity: ResolvedArg | None
    rate: Fraction | None = None  # declared, Hz
    delay: Fraction | None = None  # declared, seconds


NS = 10**9


def quality_rows(platform: str, spec: ResolvedSpec) -> list[Row]:
    """topic_property(Platform, Topic, Property, Ns): the declared stream quality as whole
    nanoseconds the rules compare: `period` (one over the rate), `delay`, and `age`, the
    oldest the freshest sample may be (a period plus the delay, what is declared of them)."""
    told = {"period": NS / spec.rate if spec.rate else None, "delay": spec.delay}
    rows: list[Row] = [
        (platform, spec.name, name, round(v * NS if name == "delay" else v))
        for name, v in told.items()
        if v is not None
    ]
    if rows:
        rows.append((platform, spec.name, "age", sum(int(r[3]) for r in rows)))
    return rows


def ontology_facts(ont: Ontology) -> Facts:
    p = ont.platform
    out: Facts = defaultdict(list)
    sorts = ont.sorts
    out["sort"] = [(p, s) for s in sorted(sorts)]
    has_super = {a for a, b in ont.subclass_of if b in sorts}
    out["subclass_of"] = [(p, a, b) for a, b in ont.subclass_of]
    out["subclass_of"] += [(p, s, THING) for s in sorted(sorts - has_super - {THING})]
    out["equivalent_class"] = [(p, a, b) for a, b in ont.equivalent]
    for f, sig in sorted(ont.features.items()):
        out["feature"].append((p, f, sig.arity))
        out["feature_arg"] += [
            (p, f, i, s) for i, allowed in enumerate(sig.arg_sorts, 1) for s in allowed
        ]
    out["individual"] = [(p, o) for o in sorted(ont.individuals)]
    reps = same_classes(ont)
    out["same_as"] = [(p, a, b) for a, b in ont.same_as]
    out["same_rep"] = [(p, o, r) for o, r in sorted(reps.items())]
    out["class_type"] = [
        (p, r, c) for r, c in sorted({(reps.get(o, o), c) for o, c in told_types(ont)})
    ]
    steps = [
        *ont.subclass_of,
        *((s, THING) for s in sorts - has_super - {THING}),
        *(e for a, b in ont.equivalent for e in ((a, b), (b, a))),
    ]
    sort_reps = equivalent_sorts(sorts, steps)
    bound_closure(ont, sort_reps, steps)
    out["sort_rep"] = [(p, c, r) for c, r in sorted(sort_reps.items())]
    out["id_property"] = [(p, o, v) for o, v in sorted(ont.ids.items(), key=str)]
    out["name_digits"] = [
        (p, o, d) for o in sorted(ont.individuals) if (d := name_digits(local_name(o))) is not None
    ]
    out["data_property"] = [(p, o, prop, v) for o, prop, v in ont.data_values]
    out["object_property"] = [(p, o, prop, x) for o, prop, x in ont.object_values]
    return out


def told_types(ont: Ontology) -> list[tuple[str, str]]:
    """Each object's told sorts: its rdf:type axioms, or owl:Thing when it has none."""
    typed = {o for o, _ in ont.types}
    return [*ont.types, *((o, THING) for o in sorted(ont.individuals - typed))]


def _named(members: Iterable[str]) -> str:
    """A class's representative: its smallest local name (the name expansion shows)."""
    return min(members, key=lambda x: (local_name(x), x))


def same_classes(ont: Ontology) -> dict[str, str]:
    """Each object → the representative of its sameAs class (union-find: linear, where the
    pairwise closure of a class of n objects has n² rows)."""
    parent = {o: o for o in ont.individuals}
    for a, b in ont.same_as:
        parent.setdefault(a, a)
        parent.setdefault(b, b)

    def root(x: str) -> str:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in ont.same_as:
        parent[root(a)] = root(b)
    classes: dict[str, list[str]] = defaultdict(list)
    for o in parent:
        classes[root(o)].append(o)
    return {o: name for members in classes.values() for name in [_named(members)] for o in members}


def equivalent_sorts(sorts: Iterable[str], steps: list[tuple[str, str]]) -> dict[str, str]:
    """Each class → the representative of its strongly connected component under ⊑ steps
    (a subClassOf cycle, or equivalentClass, makes classes equivalent).  Iterative Tarjan."""
    graph: dict[str, list[str]] = defaultdict(list)
    for a, b in steps:
        graph[a].append(b)
    nodes = list(dict.fromkeys([*sorts, *(x for step in steps for x in step)]))
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: dict[str, str] = {}
    for start in nodes:
        if start in index:
            continue
        work = [(start, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            succ = graph.get(node, [])
            if i < len(succ):
                work.append((node, i + 1))
                nxt = succ[i]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if low[node] == index[node]:
                component = []
                while True:
                    x = stack.pop()
                    on_stack.discard(x)
                    component.append(x)
                    if x == node:
                        break
                name = _named(component)
                out.update(dict.fromkeys(component, name))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return out


MIN_CLOSURE = 100_000  # rows every ontology may derive
CLOSURE_PER_FACT = 50  # and rows per told sort, object, subClassOf or membership


def bound_closure(ont: Ontology, sort_reps: dict[str, str], steps: list[tuple[str, str]]) -> None:
    """Refuse, before it is derived, a hierarchy whose closure (each sort's supersorts, each
    object's sorts: rules/ontology.dl's rep_reach and member) outgrows the ontology: a chain
    n deep gives n²/2 rows of each, a million (1.27 GB) for a 60 KB file of 1,000 sorts.
    Counted with each sort's supersorts as a set, stopping once past the bound."""
    told = len(ont.sorts) + len(ont.individuals) + len(ont.subclass_of) + len(ont.types)
    limit = max(MIN_CLOSURE, CLOSURE_PER_FACT * told)
    up: dict[str, set[str]] = defaultdict(set)
    for a, b in steps:
        if sort_reps.get(a, a) != sort_reps.get(b, b):
            up[sort_reps.get(a, a)].add(sort_reps.get(b, b))
    above: dict[str, frozenset[str]] = {}  # a representative → itself and its supersorts
    rows = 0
    for start in up:
        work = [start]
        while work:  # depth first, a sort after the sorts above it
            node = work[-1]
            missing = [b for b in up.get(node, ()) if b not in above]
            if missing:
                work += missing
                continue
            work.pop()
            if node not in above:
                above[node] = frozenset({node}.union(*(above[b] for b in up.get(node, ()))))
                rows += len(above[node])
                if rows > limit:
                    break
        if rows > limit:
            break
    rows += sum(len(above.get(sort_reps.get(c, c), ())) for _, c in ont.types)
    if rows > limit:
        raise DkError(
            f"{ont.file}: its sort hierarchy's closure holds more than {limit} rows (each "
            f"object a member of every sort above its own: is a subClassOf chain hundreds "
            f"deep?); at most {CLOSURE_PER_FACT} a told axiom, {MIN_CLOSURE} in all"
        )


@lru_cache(maxsize=1 << 16)
def name_digits(name: str) -> int | None:
    """The digits ending a name (uav12 → 12), which the thesis uses as an object's id."""
    match = _TRAILING_DIGITS.search(name)
    return int(match.group(1)) if match else None


def spec_facts(platform: str, spec: ResolvedSpec) -> Facts:
    out: Facts = defaultdict(list)
    out["topic"] = [(platform, spec.name, spec.msgtype)]
    for k, f in enumerate(spec.features, 1):
        out["topic_feature"].append((platform, spec.name, k, f.iri, f.field))
        out["topic_arg"] += [
            (platform, spec.name, k, i, a.kind, a.iri, a.id_field) for i, a in enumerate(f.args, 1)
        ]
        fields = [a.id_field for a in f.args]
        out["topic_filter"].append((platform, spec.name, k, *fields, *[""] * (3 - len(fields))))
    if spec.entity is not None:
        e = spec.entity
        out["topic_entity"] = [(platform, spec.name, e.kind, e.iri, e.id_field)]
    out["topic_property"] = quality_rows(platform, spec)
    return out


def merge(*parts: Facts) -> Facts:
    out: Facts = defaultdict(list)
    for part in parts:
        for pred, rows in part.items():
            out[pred] += rows
    return out


def rows_of(facts: Facts) -> Iterable[tuple[str, list[Row]]]:
    return ((pred, rows) for pred, rows in facts.items() if rows)
