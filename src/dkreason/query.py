"""Questions to a loaded knowledge base in the rules' own language (`dkreason query`).

A question is a rule body: `same_as(P, O, 'uav2')`, `same_rep(P, 'uav2', R) & same_rep(P, O,
R)`; its variables are the answer's columns (a `_`-named one is not shown).  Constants are
written as in rule files (local names, `prefix:Name`, full IRIs).  The design card's relation
is there as rule authors read it: `relevant_topic(Feature, Args, Topic, Filter)`, the
arguments and the filter as tuples (`relevant_topic(F, ('uav1',), T, Filter)`), asked for
the local platform's features and objects through the policy, whatever flat, padded form the
engine keeps (relevant_topic/10, which is asked only with a formula).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from .errors import DkError, RuleError, Span
from .kb import KnowledgeBase
from .match import match
from .model import GroundFeature
from .names import local_name
from .parse.formula import MAX_EXPANSION
from .policy.check import Diagnostic, bindings, given_readers, misnamed
from .policy.resolve import Names
from .policy.syntax import (
    Comparison,
    Condition,
    Literal,
    Relation,
    Rule,
    Term,
    Value,
    Var,
    parse_query,
    read_tuple,
)

Cell = Value | tuple[Value, ...]

READER = Relation(
    "relevant_topic", ("Feature", "Args", "Topic", "Filter"), "query", Span("<dkreason>")
)
"""relevant_topic/4 as rule authors read it (the design card's relation)."""


@dataclass(frozen=True, slots=True)
class Answer:
    """A question's answer: its variables, and their values in each solution (sorted).  No
    variable: one empty row if it holds, none if not."""

    query: str
    columns: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]

    def to_json(self) -> list[dict[str, object]]:
        return [
            {
                c: list(v) if isinstance(v, tuple) else v
                for c, v in zip(self.columns, row, strict=True)
            }
            for row in self.rows
        ]


@dataclass(frozen=True, slots=True)
class RelationInfo:
    """A relation as `dkreason query --relations` lists it: its rows, when they can be counted
    (None: they hold only while a formula is asked, or only with some arguments bound)."""

    relation: Relation
    rows: int | None
    note: str = ""


def ask(kb: KnowledgeBase, text: str) -> Answer:
    """The answer to a question about the knowledge base (see the module docstring)."""
    body = parse_query(text)
    if len(body) == 1 and isinstance(body[0], Literal) and _is_reader(body[0]):
        return _reader(kb, text, body[0])
    schema = kb.engine.schema
    names = Names([p.names for p in kb.platforms.values()])
    resolved = [_checked(c, schema, names) for c in body]
    columns = tuple(
        dict.fromkeys(
            v.name
            for c in resolved
            for v in ((c.left, c.right) if isinstance(c, Comparison) else c.args)
            if isinstance(v, Var) and not v.name.startswith("_")
        )
    )
    _bound_in_time(kb, resolved, columns, text)
    lit = resolved[0]
    if len(resolved) == 1 and isinstance(lit, Literal) and not lit.negated:
        found = kb.engine.query(
            lit.predicate, *(None if isinstance(a, Var) else a for a in lit.args)
        )
        rows = {_project(lit.args, row, columns) for row in found}
    else:
        rows = set(kb.engine.solve(resolved, columns))
    return Answer(text, columns, tuple(sorted(rows, key=_order)))


def _is_reader(lit: Literal) -> bool:
    return lit.predicate == READER.name and len(lit.args) == READER.arity and not lit.negated


def _checked(c: Condition, schema: dict[str, Relation], names: Names) -> Condition:
    """The condition with its relation declared and its constants resolved."""
    span = Span("<query>")
    terms = (c.left, c.right) if isinstance(c, Comparison) else c.args
    for t in terms:
        if isinstance(t, Var) and t.name[0].islower():
            raise DkError(
                f"{t.name} is a variable (variables start with an upper-case letter or _): "
                f"write '{t.name}' for the constant"
            )
        if read_tuple(t) is not None:
            raise DkError(
                "a tuple is an argument of relevant_topic(Feature, Args, Topic, Filter) only"
            )
    resolved = tuple(names.iri(t, span) if isinstance(t, str) and t else t for t in terms)
    if isinstance(c, Comparison):
        return Comparison(c.op, resolved[0], resolved[1], c.span, c.spans)
    message = misnamed(c.predicate, len(c.args), schema)
    if message is not None:
        raise RuleError(message, c.span)
    return Literal(c.predicate, resolved, c.negated, c.span, c.spans)


def _bound_in_time(
    kb: KnowledgeBase, body: list[Condition], columns: tuple[str, ...], text: str
) -> None:
    """Each variable is bound before a negation or a comparison reads it, and each relation
    is asked with the arguments its rules need bound (dkreason.policy.check)."""
    head = Literal("query", tuple(map(Var, columns)), span=Span("<query>"))
    problems, calls = bindings(
        Rule(head, tuple(body), text, Span("<query>")),
        (False,) * len(columns),
        kb.engine.modes.rules,
    )
    problems += [p for predicate, mask in calls for p in kb.engine.modes.problems(predicate, mask)]
    if problems:
        first: Diagnostic = problems[0]
        where = "" if first.span.file == "<query>" else f" ({first.span})"
        raise DkError(f"cannot ask {text.strip()}: {first.message}{where}")


def _project(
    args: tuple[Term, ...], row: tuple[Value, ...], columns: tuple[str, ...]
) -> tuple[Cell, ...]:
    """The row's values of the named variables, in the answer's column order."""
    by_name: dict[str, Value] = {}
    for a, v in zip(args, row, strict=True):
        if isinstance(a, Var):
            by_name.setdefault(a.name, v)
    return tuple(by_name[c] for c in columns)


def _order(row: tuple[Cell, ...]) -> list[tuple[str, object]]:
    return [(type(v).__name__, v) for v in row]


def _reader(kb: KnowledgeBase, text: str, lit: Literal) -> Answer:
    """relevant_topic(Feature, Args, Topic, Filter): the local platform's ground features the
    arguments allow, matched as a formula's are."""
    feature, args, topic, filter_ = lit.args
    local = kb.platform(kb.local)
    span = Span("<query>")
    iris = (
        [local.names.resolve(feature, ("feature",), span)]
        if isinstance(feature, str)
        else sorted(local.ontology.features)
    )
    given = read_tuple(args)
    if isinstance(args, str | int) and given is None:
        raise DkError("relevant_topic's Args is a tuple: ('uav1',), or a variable")
    objects = (
        None
        if given is None
        else tuple(local.names.resolve(str(o), ("object",), span) for o in given)
    )
    ground: list[GroundFeature] = []
    for iri in iris:
        signature = local.ontology.features[iri]
        if objects is not None:
            if len(objects) != signature.arity:
                continue
            tuples = [objects]
        else:
            tuples = list(
                itertools.product(*(_members(kb, sorts) for sorts in signature.arg_sorts))
            )
        if len(ground) + len(tuples) > MAX_EXPANSION:
            raise DkError(
                f"{text.strip()} asks for more than {MAX_EXPANSION} ground features: "
                "bind Feature or Args"
            )
        ground += [
            GroundFeature(local_name(iri), tuple(map(local_name, t)), iri, t) for t in tuples
        ]
    matches, _ = match(kb, ground)
    wanted_filter = read_tuple(filter_)
    rows = {
        (g.iri, g.arg_iris, m.topic, tuple(m.ids))
        for m in matches
        for g in [ground[m.query]]
        if (not isinstance(topic, str) or topic == m.topic)
        and (wanted_filter is None or wanted_filter == tuple(m.ids))
    }
    variables = [(i, a.name) for i, a in enumerate(lit.args) if isinstance(a, Var)]
    columns = tuple(dict.fromkeys(name for _, name in variables if not name.startswith("_")))
    index = {name: i for i, name in reversed(variables)}
    cells = {tuple(row[index[c]] for c in columns) for row in rows}
    return Answer(text, columns, tuple(sorted(cells, key=_order)))


def _members(kb: KnowledgeBase, sorts: tuple[str, ...]) -> list[str]:
    """The local objects of any of the sorts (subsorts and sameAs included)."""
    return sorted(
        {str(o) for s in sorts for _, o, _ in kb.engine.query("instance_of", kb.local, None, s)}
    )


def relations(kb: KnowledgeBase) -> list[RelationInfo]:
    """Every declared relation with its rows, in the order the files declare them, then the
    reader's relevant_topic/4.  Rows are counted where they are stored (inputs, views) and
    for what dkreason asks with every argument free (queries, hooks); a relation only rules
    read is derived when asked, and counting all its rows could cost what no rule asks."""
    engine = kb.engine
    stored = engine.sizes()
    per_formula = given_readers(engine.schema, engine.rules)
    out = []
    for relation in engine.schema.values():
        name = relation.name
        if name in stored:
            out.append(RelationInfo(relation, stored[name][1]))
        elif relation.kind in ("input", "view"):
            out.append(RelationInfo(relation, 0))
        elif relation.kind == "given":
            out.append(RelationInfo(relation, None, "given while a formula is asked"))
        elif name in per_formula:
            out.append(RelationInfo(relation, None, f"per formula: reads {per_formula[name]}"))
        elif engine.askable(name, [None] * relation.arity):
            out.append(RelationInfo(relation, None, "asked with some arguments bound"))
        elif relation.kind in ("query", "hook"):
            out.append(RelationInfo(relation, len(engine.query(name, *[None] * relation.arity))))
        else:
            out.append(RelationInfo(relation, None, "derived when asked"))
    out.append(RelationInfo(READER, None, "asked per feature of the local platform"))
    return out
