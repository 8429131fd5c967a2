"""Formulas → a plan: each formula parsed once, checked once and expanded once into its
instances (one per binding of its outermost quantifiers' variables), their ground features as
typed keys.  Matching and progression both start from the plan, so they can never disagree on
which features a formula reads."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

from .check import check_formula
from .expand import Binder, Instance, expand, union
from .kb import KnowledgeBase
from .model import FeatureKey, GroundFeature
from .parse.formula import BoolConst, Formula, chain, formula_warnings, parse_formula

T = TypeVar("T")
Bindings = tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class Parsed:
    """A formula as written and its syntax tree (quantifiers still in)."""

    text: str
    tree: Formula


def parse(formulas: Sequence[str | Parsed]) -> tuple[Parsed, ...]:
    """Each formula parsed, once: those parsed already are kept."""
    return tuple(f if isinstance(f, Parsed) else Parsed(f, parse_formula(f)) for f in formulas)


@dataclass(frozen=True, slots=True)
class FormulaPlan:
    """One formula as written: its outermost quantifiers (`prefix`, each with the objects it
    ranges over) and an instance per binding of their variables (a formula without them is
    its one instance, with no bindings).  `warnings`: what it probably does not mean, one
    line each (a comparison of a term with itself)."""

    text: str
    prefix: tuple[Binder, ...]
    instances: tuple[Instance, ...]
    warnings: tuple[str, ...] = ()

    @property
    def tree(self) -> Formula:
        """The whole formula without quantifiers: its instances joined as its prefix says."""
        trees = {i.bindings: i.tree for i in self.instances}
        return fold(
            self.prefix,
            trees.__getitem__,
            lambda op, parts: (
                chain("and" if op == "forall" else "or", parts)
                if parts
                else BoolConst(op == "forall")
            ),
        )

    @property
    def ground(self) -> tuple[GroundFeature, ...]:
        """The ground features of every instance, each once, in order of first use."""
        return union(i.ground for i in self.instances)

    @property
    def keys(self) -> tuple[FeatureKey, ...]:
        return tuple(g.key for g in self.ground)


def fold(
    prefix: Sequence[Binder], leaf: Callable[[Bindings], T], join: Callable[[str, list[T]], T]
) -> T:
    """A value for a formula from its instances': `leaf` of each binding, joined level by
    level by the quantifier (`join(op, parts)`, parts in the order of the binder's objects)."""

    def level(n: int, bound: Bindings) -> T:
        if n == len(prefix):
            return leaf(bound)
        b = prefix[n]
        return join(b.op, [level(n + 1, (*bound, (b.var, o))) for o in b.objects])

    return level(0, ())


@dataclass(frozen=True, slots=True)
class Plan:
    formulas: tuple[FormulaPlan, ...]

    @property
    def ground(self) -> tuple[GroundFeature, ...]:
        """Every ground feature of every formula, each once, in order of first use."""
        return union(f.ground for f in self.formulas)

    @property
    def text(self) -> str:
        return "; ".join(f.text for f in self.formulas)

    @property
    def warnings(self) -> tuple[str, ...]:
        return tuple(w for f in self.formulas for w in f.warnings)


def plan(kb: KnowledgeBase, formulas: Sequence[str | Parsed]) -> Plan:
    out = []
    for f in parse(formulas):
        expansion = expand(kb, f.tree, check_formula(kb, f.tree))
        warnings = tuple(formula_warnings(f.tree))
        out.append(FormulaPlan(f.text, expansion.prefix, expansion.instances, warnings))
    return Plan(tuple(out))
