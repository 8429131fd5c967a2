"""Formulas → a plan: each formula parsed once, checked once and expanded once, its ground
features as typed keys.  Matching and progression both start from the plan, so they can never
disagree on which features a formula reads."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from .check import check_formula
from .expand import expand
from .kb import KnowledgeBase
from .model import FeatureKey, GroundFeature
from .parse.formula import Formula, parse_formula


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
    """One formula as written, its quantifier-free tree, and the ground features it reads."""

    text: str
    tree: Formula
    ground: tuple[GroundFeature, ...]

    @property
    def keys(self) -> tuple[FeatureKey, ...]:
        return tuple(g.key for g in self.ground)


@dataclass(frozen=True, slots=True)
class Plan:
    formulas: tuple[FormulaPlan, ...]

    @property
    def ground(self) -> tuple[GroundFeature, ...]:
        """Every ground feature of every formula, each once, in order of first use."""
        seen: dict[FeatureKey, GroundFeature] = {}
        for f in self.formulas:
            for g in f.ground:
                seen.setdefault(g.key, g)
        return tuple(seen.values())

    @property
    def text(self) -> str:
        return "; ".join(f.text for f in self.formulas)


def plan(kb: KnowledgeBase, formulas: Sequence[str | Parsed]) -> Plan:
    out = []
    for f in parse(formulas):
        expansion = expand(kb, f.tree, check_formula(kb, f.tree))
        out.append(FormulaPlan(f.text, expansion.tree, expansion.ground))
    return Plan(tuple(out))
