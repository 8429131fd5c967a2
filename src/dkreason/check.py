"""Check a formula's features against the local ontology (thesis 5.4): the feature exists,
the arity fits, each constant names an object and each variable a sort, and every argument fits
the feature's signature.  Errors point into the formula."""

from __future__ import annotations

from dataclasses import dataclass

from .errors import NameError_, SortError
from .facts import ResolvedArg
from .kb import KnowledgeBase
from .model import Arg, FeatureRef
from .names import local_name
from .parse.formula import Formula, features, quantifiers


@dataclass(frozen=True, slots=True)
class CheckedFeature:
    """A formula feature with IRIs: objects for constants, sorts for variables."""

    ref: FeatureRef
    iri: str
    arg_iris: tuple[str, ...]


def check_formula(kb: KnowledgeBase, formula: Formula) -> list[CheckedFeature]:
    local = kb.platform(kb.local)
    for q in quantifiers(formula):
        local.names.resolve(q.sort, ("sort",), q.span)
    checked: list[CheckedFeature] = []
    for ref in features(formula):
        try:
            iri = local.names.resolve(ref.name, ("feature",), ref.span)
        except NameError_:  # an adapter may know why it is none
            why = [w for x, w in local.ontology.unadapted.items() if local_name(x) == ref.name]
            if why:
                raise NameError_(
                    f"{ref.name} is no feature on {kb.local}: {why[0]}", ref.span
                ) from None
            raise
        arity = local.ontology.features[iri].arity
        if len(ref.args) != arity:
            raise SortError(
                f"{ref.name} takes {arity} argument{'s' if arity != 1 else ''}, "
                f"not {len(ref.args)}",
                ref.span,
            )
        args = tuple(
            local.names.resolve(a.sort, ("sort",), a.span)
            if a.sort is not None
            else local.names.resolve(a.name, ("object",), a.span)
            for a in ref.args
        )
        checked.append(CheckedFeature(ref, iri, args))
    asks: dict[tuple[str, int, str, str], tuple[int, Arg]] = {}  # first use of each argument
    for n, c in enumerate(checked):
        for i, (a, x) in enumerate(zip(c.ref.args, c.arg_iris, strict=True), 1):
            asks.setdefault((c.iri, i, x, "sort" if a.is_variable else "object"), (n, a))
    if asks:
        fitting = set(kb.engine.ask("arg_fits", {"check_arg": list(asks)}, None, None, None))
        for (f, i, x, _kind), (n, arg) in asks.items():
            if (f, i, x) not in fitting:
                how = (
                    kb.misfit(local, f, i, x)
                    if not arg.is_variable
                    else f"variable {arg.name} ranges over {local_name(x)}, "
                    + kb.misfit(local, f, i, ResolvedArg("some", x, ""))
                    .removeprefix(f"sort {local_name(x)} ")
                    .replace("is not", "which is not", 1)
                )
                raise SortError(f"argument {i} of {checked[n].ref.name}: {how}", arg.span)
    return checked
