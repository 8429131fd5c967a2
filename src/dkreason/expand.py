"""Expand quantified arguments over the local platform's objects of the sort (thesis 4.2):
subsorts, equivalent sorts and sorts inherited through sameAs included.  Objects that are
sameAs each other expand once, named by the smallest local name among them."""

from __future__ import annotations

import itertools
import math
from collections import defaultdict

from .check import CheckedFeature
from .errors import DkError
from .kb import KnowledgeBase
from .model import GroundFeature
from .names import local_name
from .parse.formula import MAX_EXPANSION


def expand(kb: KnowledgeBase, checked: list[CheckedFeature]) -> list[GroundFeature]:
    members_of = members(kb, {iri for c in checked
                            for a, iri in zip(c.ref.args, c.arg_iris, strict=True)
                            if a.is_variable})
    out: dict[tuple[str, tuple[str, ...]], GroundFeature] = {}
    for c in checked:
        variables = list(dict.fromkeys(a.name for a in c.ref.args if a.is_variable))
        sort_of = {a.name: iri for a, iri in zip(c.ref.args, c.arg_iris, strict=True)
                   if a.is_variable}
        count = math.prod(len(members_of[sort_of[v]]) for v in variables)
        if count > MAX_EXPANSION:
            raise DkError(f"{c.ref.span}: {c.ref.name} expands to {count} ground features, "
                          f"more than the {MAX_EXPANSION} one formula takes")
        for values in itertools.product(*(members_of[sort_of[v]] for v in variables)):
            env = dict(zip(variables, values, strict=True))
            iris = tuple(env[a.name] if a.is_variable else iri
                         for a, iri in zip(c.ref.args, c.arg_iris, strict=True))
            names = tuple(local_name(env[a.name]) if a.is_variable else a.name
                          for a in c.ref.args)
            out.setdefault((c.iri, iris), GroundFeature(c.ref.name, names, c.iri, iris, c.ref.span))
    return list(out.values())


def members(kb: KnowledgeBase, sorts: set[str]) -> dict[str, list[str]]:
    """Each sort's objects, one representative per sameAs class, sorted by local name."""
    if not sorts:
        return {}
    pairs = kb.engine.ask("expansion", {"expand_sort": [(s,) for s in sorted(sorts)]},
                          None, None, None)
    same: dict[str, set[str]] = defaultdict(set)
    objects: dict[str, set[str]] = defaultdict(set)
    for sort, obj, other in pairs:
        assert isinstance(sort, str) and isinstance(obj, str) and isinstance(other, str)
        same[obj].add(other)
        objects[sort].add(obj)
    rep = {o: min(same[o], key=lambda x: (local_name(x), x)) for o in same}
    return {s: sorted({rep[o] for o in objects.get(s, ())}, key=lambda x: (local_name(x), x))
            for s in sorts}
