"""Expand a checked formula's quantifiers over the local platform's objects of the sort
(thesis 4.2): subsorts, equivalent sorts and sorts inherited through sameAs included.  Objects
that are sameAs each other expand once, named by the smallest local name among them.

The outermost quantifiers (`forall c in Car:` …, before any other operator) make instances:
one formula per binding of their variables, each judged on its own (parametric monitoring);
quantifiers anywhere else expand in place into conjunctions and disjunctions.

One walk gives both halves of each instance: the quantifier-free tree the progressor runs,
and the ground features the matcher finds topics for, so the two can never disagree."""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import product
from typing import Any

from .check import CheckedFeature
from .errors import DkError
from .kb import KnowledgeBase
from .model import Arg, FeatureKey, FeatureRef, GroundFeature
from .names import local_name
from .parse.formula import (
    MAX_EXPANSION,
    Atom,
    BoolConst,
    Connective,
    Formula,
    Not,
    Observed,
    Quant,
    Ref,
    Temporal,
    Until,
    chain,
    quantifiers,
)


@dataclass(frozen=True, slots=True)
class Binder:
    """One variable of a formula's outermost quantifiers (`forall c in Car`) and the objects
    it ranges over (local names, sorted: as the sort had them when expanded)."""

    op: str  # forall exists
    var: str
    sort: str
    objects: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Instance:
    """The formula for one binding of its outermost quantifiers' variables (`bindings`:
    variable → object's local name, in the quantifiers' order; none when it has none): its
    quantifier-free tree and the ground features it reads, each once, in order."""

    bindings: tuple[tuple[str, str], ...]
    tree: Formula
    ground: tuple[GroundFeature, ...]

    @property
    def keys(self) -> tuple[FeatureKey, ...]:
        return tuple(g.key for g in self.ground)


@dataclass(frozen=True, slots=True)
class Expansion:
    """A formula's outermost quantifiers and one instance per binding of their variables."""

    prefix: tuple[Binder, ...]
    instances: tuple[Instance, ...]

    @property
    def ground(self) -> tuple[GroundFeature, ...]:
        """The ground features of every instance, each once, in order of first use."""
        return union(i.ground for i in self.instances)


def union(grounds: Iterable[tuple[GroundFeature, ...]]) -> tuple[GroundFeature, ...]:
    """Ground features, each once, in order of first use."""
    seen: dict[FeatureKey, GroundFeature] = {}
    for ground in grounds:
        for g in ground:
            seen.setdefault(g.key, g)
    return tuple(seen.values())


def expand(kb: KnowledgeBase, formula: Formula, checked: list[CheckedFeature]) -> Expansion:
    local = kb.platform(kb.local)
    by_ref = {c.ref: c for c in checked}
    sorts = {q.sort: local.names.resolve(q.sort, ("sort",), q.span) for q in quantifiers(formula)}
    members_of = members(kb, set(sorts.values()))
    size = _size(formula, lambda sort: len(members_of[sorts[sort]]))
    if size > MAX_EXPANSION:
        raise DkError(
            f"{next(quantifiers(formula)).span}: the quantifiers expand to {size} "
            f"subformulas, more than the {MAX_EXPANSION} one formula takes"
        )
    outer: list[Quant] = []
    body = formula
    while isinstance(body, Quant):
        outer.append(body)
        body = body.body
    objects = [members_of[sorts[q.sort]] for q in outer]
    prefix = tuple(
        Binder(q.op, q.var, q.sort, tuple(local_name(o) for o in os))
        for q, os in zip(outer, objects, strict=True)
    )
    instances = []
    for binding in product(*objects):
        env = {q.var: (q.sort, o) for q, o in zip(outer, binding, strict=True)}
        tree, ground = _walk(body, env, by_ref, members_of, sorts)
        names = tuple((q.var, local_name(o)) for q, o in zip(outer, binding, strict=True))
        instances.append(Instance(names, tree, ground))
    return Expansion(prefix, tuple(instances))


def _walk(
    formula: Formula,
    bound: dict[str, tuple[str, str]],
    by_ref: dict[FeatureRef, CheckedFeature],
    members_of: dict[str, list[str]],
    sorts: dict[str, str],
) -> tuple[Formula, tuple[GroundFeature, ...]]:
    """`formula` with its variables `bound` (var → (sort, object IRI)) and its quantifiers
    expanded in place, and the ground features it reads."""
    ground: dict[tuple[str, tuple[str, ...]], GroundFeature] = {}

    def walk(node: Any, env: dict[str, tuple[str, str]]) -> Any:  # var → (sort, object IRI)
        if isinstance(node, Quant):
            parts = [
                walk(node.body, {**env, node.var: (node.sort, o)})
                for o in members_of[sorts[node.sort]]
            ]
            op = "and" if node.op == "forall" else "or"
            return chain(op, parts) if parts else BoolConst(op == "and")
        if isinstance(node, Atom | Ref | Observed):
            f = node.feature
            c = by_ref[
                FeatureRef(
                    f.name,
                    tuple(
                        Arg(a.name, env[a.name][0] if a.name in env else None, a.span)
                        for a in f.args
                    ),
                    f.span,
                )
            ]
            iris = tuple(
                env[a.name][1] if a.name in env else iri
                for a, iri in zip(f.args, c.arg_iris, strict=True)
            )
            names = tuple(local_name(env[a.name][1]) if a.name in env else a.name for a in f.args)
            ground.setdefault((c.iri, iris), GroundFeature(f.name, names, c.iri, iris, f.span))
            return type(node)(
                FeatureRef(
                    f.name,
                    tuple(Arg(n, None, a.span) for n, a in zip(names, f.args, strict=True)),
                    f.span,
                )
            )
        changes = {
            attr: walk(getattr(node, attr), env)
            for attr in ("arg", "left", "right")
            if hasattr(node, attr)
        }
        return dataclasses.replace(node, **changes) if changes else node

    tree = walk(formula, bound)
    return tree, tuple(ground.values())


def _size(f: Any, count: Any) -> int:
    """Atoms and comparisons of `f` once expanded, counted without expanding."""
    if isinstance(f, Quant):
        return int(count(f.sort)) * _size(f.body, count)
    if isinstance(f, Connective | Until):
        return _size(f.left, count) + _size(f.right, count)
    if isinstance(f, Not | Temporal):
        return _size(f.arg, count)
    return 1


def members(kb: KnowledgeBase, sorts: set[str]) -> dict[str, list[str]]:
    """Each sort's objects, one per sameAs class (named by its smallest local name, the class's
    representative), sorted by local name."""
    if not sorts:
        return {}
    rows = kb.engine.ask(
        "expansion", {"expand_sort": [(s,) for s in sorted(sorts)]}, None, None, None
    )
    classes: dict[str, set[str]] = defaultdict(set)
    for sort, _obj, cls in rows:
        classes[str(sort)].add(str(cls))
    return {s: sorted(classes.get(s, ()), key=lambda x: (local_name(x), x)) for s in sorts}
