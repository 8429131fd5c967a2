"""Ontologies as they are written → the features the class pattern gives, through adapters.

An adapter is a rule file (rules/adapters/NAME.dl, or one's own, chosen per platform by the
config's `adapters = [...]`) over every triple of the ontology (rules/adapters/schema.dl).  It
runs once, when the platform's ontology is read, in an engine of its own, and what it derives
joins the told axioms: from then on an adapted feature is a feature like any other (matching,
quantifiers, federation, explanations, the cache).  No Python per vocabulary.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from .datalog import Datalog
from .errors import Span
from .inputs.files import read_text
from .model import Adapted, Ontology, Signature
from .names import NameIndex, local_name
from .parse.config import ADAPTER_SCHEMA, SHIPPED_RULES
from .parse.owl import ARG, ARITY
from .policy.load import shown
from .policy.resolve import Names, resolve
from .policy.syntax import (
    Comparison,
    Condition,
    Literal,
    Row,
    Rule,
    RuleFile,
    Term,
    Value,
    Var,
)
from .policy.tables import read_rule_file

THING = "http://www.w3.org/2002/07/owl#Thing"

# The prefixes an adapter's constants may use whatever the ontology declares (its own are
# usable too): the vocabularies adapters are written for.
PREFIXES = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
    "sosa": "http://www.w3.org/ns/sosa/",
    "ssn": "http://www.w3.org/ns/ssn/",
    "saref": "https://saref.etsi.org/core/",
    "schema": "https://schema.org/",
}


@dataclass(frozen=True, slots=True)
class Adaptation:
    """An ontology with what its adapters derived, and one warning line per entity that looked
    like a feature but became none."""

    ontology: Ontology
    warnings: tuple[str, ...]


def adapt(
    ont: Ontology, told: Sequence[Row], adapters: Sequence[Path], reasoning: str = "none"
) -> Adaptation:
    """Run `adapters` over the ontology's triples `told` (subject, predicate, object) under the
    platform's `reasoning`; a rule file the checker refuses raises its one RuleError."""
    p = ont.platform
    names = Names([NameIndex(p, {**ont.prefixes, **PREFIXES}, {})])
    files = [
        resolve(_rule_file(path, shown(path, None), read_text(path)), names)
        for path in (ADAPTER_SCHEMA, *adapters)
    ]
    engine = Datalog()
    notes = [str(d) for d in engine.load(files)]
    wanted = _triples_read(files)
    engine.assert_rows("triple", [(p, *t) for t in told if wanted is None or wanted(t)])
    engine.assert_rows("reasoning", [(p, reasoning)])
    engine.assert_rows(
        "class_pattern",
        [
            (p, x)
            for x in {x for t in told for x in t if isinstance(x, str)}
            if ARG.search(x) or local_name(x) in ARITY
        ],
    )
    engine.materialize()

    def rows(relation: str, arity: int) -> list[Row]:
        return sorted(engine.query(relation, p, *([None] * (arity - 1))), key=repr)

    sorts: dict[str, dict[int, list[str]]] = defaultdict(lambda: defaultdict(list))
    for _, f, i, s in rows("adapted_arg", 4):
        sorts[str(f)][int(i)].append(str(s))
    axioms: dict[str, list[tuple[str, str, str]]] = defaultdict(list)
    for _, f, s, pred, o in rows("adapted_axiom", 5):
        # an object and its property individual, tied whichever way the told triple points
        # (ssn:hasProperty from the object, ssn:isPropertyOf to it): shown as told
        ahead = bool(engine.query("triple", p, s, pred, o)) or not engine.query(
            "triple", p, o, pred, s
        )
        axioms[str(f)].append((str(s), str(pred), str(o)) if ahead else (str(o), str(pred), str(s)))
    makers = [r for f in files for r in f.rules if r.head.predicate == "adapted_feature"]
    features = dict(ont.features)
    adapted = dict(ont.adapted)
    ids: list[str] = []
    for row in rows("adapted_feature", 3):
        _, f, arity = (str(row[0]), str(row[1]), int(row[2]))
        if local_name(f) == "id":  # the id policy's, never a feature
            ids.append(f)
            continue
        if f in features:  # the class pattern's
            continue
        features[f] = Signature(
            f, tuple(tuple(sorts[f][i]) or (THING,) for i in range(1, arity + 1))
        )
        rule = next((r.span for r in makers if _made(engine, r, row)), None)
        fact = engine.told.get(("adapted_feature", *row), Span(ADAPTER_SCHEMA.name))
        adapted[f] = Adapted(rule or fact, tuple(axioms[f]))
    new = features.keys() - ont.features.keys()
    equivalent = [(str(a), str(b)) for _, a, b in rows("adapted_equivalent", 3)]
    warned = [(str(x), str(why)) for _, x, why in rows("adapter_warning", 3)]
    notes += [
        f"{p}: {local_name(x)} ({ont.file}) becomes no feature: {why}"
        for x, why in warned
        if x not in features
    ]
    unadapted = {
        **{str(x): str(why) for _, x, why in rows("no_feature", 3)},
        **{f: "it is the id property (objects' ids, never a feature)" for f in ids},
        **dict(warned),
    }
    adapted_ont = replace(
        ont,
        classes=ont.classes | new,
        features=features,
        equivalent=tuple(sorted({*ont.equivalent, *equivalent})),
        individuals=ont.individuals - new,
        types=tuple(t for t in ont.types if t[0] not in new),
        adapted=adapted,
        unadapted={x: why for x, why in unadapted.items() if x not in features},
        observations=tuple(
            sorted({(str(s), str(f), str(o)) for _, s, f, o in rows("observes", 4)})
        ),
    )
    return Adaptation(adapted_ont, tuple(dict.fromkeys(notes)))


def axiom_text(axiom: tuple[str, str, str], prefixes: Mapping[str, str]) -> str:
    """A told triple as explanations show it: `altitude rdfs:domain UAV`."""
    s, p, o = axiom
    short = next(
        (
            f"{k}:{p.removeprefix(ns)}"
            for k, ns in {**prefixes, **PREFIXES}.items()
            if k and p.startswith(ns)
        ),
        local_name(p),
    )
    return f"{local_name(s)} {short} {local_name(o)}"


def origin(ont: Ontology, feature: str) -> str:
    """Where a feature comes from, in words: the class pattern, or the adapter rule that made
    it (file:line) and the told axioms it rests on."""
    made = ont.adapted.get(feature)
    if made is None:
        return f"class pattern ({ont.file})"
    told = "; ".join(axiom_text(a, ont.prefixes) for a in made.axioms)
    return f"adapter rule {made.rule}" + (f", from {told} ({ont.file})" if told else "")


@lru_cache(maxsize=32)
def _rule_file(path: Path, name: str, text: str) -> RuleFile:
    """An adapter file parsed once for every platform that names it (`name`: as messages show
    it; `text`: what it holds now, so an edited file is parsed again)."""
    return read_rule_file(path, name, path.resolve().is_relative_to(SHIPPED_RULES.resolve()))


def _triples_read(files: Sequence[RuleFile]) -> Callable[[Row], bool] | None:
    """Which triples the files' rules can read, by predicate and object: each a triple literal
    names, or that its variable takes from a relation only facts tell (sosa.dl's
    `has_property(Q) & triple(P, O, Q, I)`), an object a variable holds being any.  Only those
    triples are asserted: an adapter reads a few of an ontology's many (properties.dl reads
    `rdf:type` only as `owl:DatatypeProperty` and the like, not every object's type).  None:
    some rule reads triples of any predicate."""
    facts: dict[str, list[Row]] = defaultdict(list)
    for fact in (x for f in files for x in f.facts):
        facts[fact.predicate].append(fact.row)
    rules = [r for f in files for r in f.rules]
    told_only = facts.keys() - {r.head.predicate for r in rules}

    def values(term: Term, body: Sequence[Condition]) -> set[Value] | None:
        if not isinstance(term, Var):
            return {term}
        taken = [
            {row[i] for row in facts[b.predicate]}
            for b in body
            if isinstance(b, Literal) and not b.negated and b.predicate in told_only
            for i, arg in enumerate(b.args)
            if arg == term
        ]
        return taken[0] if taken else None

    read: dict[Value, set[Value] | None] = {}
    for rule in rules:
        for literal in (b for b in rule.body if isinstance(b, Literal) and b.predicate == "triple"):
            predicates, objects = (
                values(literal.args[2], rule.body),
                values(literal.args[3], rule.body),
            )
            if predicates is None:
                return None
            for predicate in predicates:
                known = read.setdefault(predicate, set())
                read[predicate] = None if known is None or objects is None else known | objects

    def wanted(triple: Row) -> bool:
        objects = read.get(triple[1], set())
        return objects is None or triple[2] in objects

    return wanted


def _made(engine: Datalog, rule: Rule, row: Row) -> bool:
    """Whether `rule` derives `row`: its body holds with its head bound to the row."""
    bound: dict[str, Value] = {}
    for term, value in zip(rule.head.args, row, strict=True):
        if isinstance(term, Var):
            if bound.setdefault(term.name, value) != value:
                return False
        elif term != value:
            return False

    def at(t: Term) -> Term:
        return bound.get(t.name, t) if isinstance(t, Var) else t

    def condition(c: Condition) -> Condition:
        if isinstance(c, Comparison):
            return replace(c, left=at(c.left), right=at(c.right))
        return replace(c, args=tuple(map(at, c.args)))

    return bool(engine.solve([condition(c) for c in rule.body], []))
