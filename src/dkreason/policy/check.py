"""Static checks of a matching policy, as Soufflé makes them: run on the whole policy before
any of it reaches the engine, and by `dkreason rules check`.

Errors: a relation used but not declared, or with another arity, or declared twice; one
dkreason asks that nothing derives; a rule deriving an input; a fact for what dkreason gives
per formula; a variable needed before anything binds it (range restriction, below); a negation
cycle (stratification: pyDatalog would loop on it, or take a relation's negation of itself as
true); a view that reads what is given per formula.  Warnings: a variable used once; a name
that is a variable because it starts with a lower-case letter; a constant no fact holds; a
relation of one's own declared but never derived, or derived but never read.

Range restriction follows how pyDatalog evaluates: top-down, each body from left to right.
What dkreason asks (query), views, hooks and relations no rule reads are asked with every
argument free, so each head variable must be bound by a positive atom of the body.  A relation
only rules read is asked with the arguments its readers bind, and its rules may take those as
bound (rules/matching.dl's sort_match tests a candidate's padding before it looks up topics).
A negated atom, and a comparison other than `X == bound`, needs its variables bound to its
left.
"""

from __future__ import annotations

import difflib
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

from ..errors import Span
from ..facts import equivalent_sorts
from ..model import BRIDGE_TYPES
from .syntax import Comparison, Fact, Literal, Relation, Rule, RuleFile, Term, Var

Mask = tuple[bool, ...]  # per argument: bound when asked
Call = tuple[str, Mask]

# Constants the schema gives a meaning to (bridge types, argument kinds, answers): never
# reported as held by no fact.
KEYWORDS = frozenset({*BRIDGE_TYPES, "object", "some", "every", "topic", "rejected", "no_id"})


@dataclass(frozen=True, slots=True)
class Diagnostic:
    severity: str  # 'error' or 'warning'
    message: str
    span: Span

    def __str__(self) -> str:
        return f"{self.span}: {self.message}"


@dataclass(frozen=True, slots=True)
class Known:
    """What the facts hold, for the constants check: whether a value occurs in a fact, and the
    known name nearest to one that does not."""

    holds: Callable[[str], bool]
    near: Callable[[str], str | None]


def _error(message: str, span: Span) -> Diagnostic:
    return Diagnostic("error", message, span)


def _warning(message: str, span: Span) -> Diagnostic:
    return Diagnostic("warning", message, span)


def check(files: Sequence[RuleFile], known: Known | None = None) -> list[Diagnostic]:
    """Every error, then every warning, of the policy these files make (`known`: the facts'
    values, for the constants check; none without a knowledge base)."""
    relations, errors = declared(files)
    rules = [rule for f in files for rule in f.rules]
    facts = [fact for f in files for fact in f.facts]
    errors += _names(relations, rules, facts, files)
    if errors:  # the deeper checks read every atom by its declaration
        return errors
    told = {fact.predicate for fact in facts} | {t.relation for f in files for t in f.tables}
    errors += _kinds(relations, rules, facts, told)
    modes = Modes(relations, rules)
    errors += modes.entry_problems()
    errors += _strata(rules)
    errors += _views(relations, rules)
    return errors + _warnings(files, relations, rules, told, known)


def declared(files: Sequence[RuleFile]) -> tuple[dict[str, Relation], list[Diagnostic]]:
    """Every relation the files declare, and each declared twice."""
    relations: dict[str, Relation] = {}
    errors = []
    for relation in (r for f in files for r in f.relations):
        first = relations.setdefault(relation.name, relation)
        if first is not relation:
            errors.append(
                _error(f"{relation.name} is declared twice (first at {first.span})", relation.span)
            )
    return relations, errors


def _names(
    relations: dict[str, Relation],
    rules: list[Rule],
    facts: list[Fact],
    files: Sequence[RuleFile],
) -> list[Diagnostic]:
    """Every relation named is declared, with its arity."""
    used: list[tuple[str, int, Span]] = [
        (lit.predicate, len(lit.args), lit.span)
        for rule in rules
        for lit in (rule.head, *(b for b in rule.body if isinstance(b, Literal)))
    ]
    used += [(fact.predicate, len(fact.row), fact.span) for fact in facts]
    used += [(t.relation, -1, t.span) for f in files for t in f.tables]
    return [
        _error(message, span)
        for name, arity, span in used
        if (message := misnamed(name, arity, relations)) is not None
    ]


def misnamed(name: str, arity: int, relations: dict[str, Relation]) -> str | None:
    """Why a relation cannot be named with this arity (-1: any), if it cannot: it is not
    declared (and the declared name nearest to it), or declared with another arity."""
    relation = relations.get(name)
    if relation is None:
        near = difflib.get_close_matches(name, relations, 1)
        hint = (
            f" (did you mean {near[0]}/{relations[near[0]].arity}?)"
            if near
            else " (declare it with `.decl`)"
        )
        return f"undeclared relation {f'{name}/{arity}' if arity >= 0 else name}{hint}"
    if arity >= 0 and arity != relation.arity:
        return (
            f"{name} has {relation.arity} columns ({', '.join(relation.columns)}, "
            f"declared at {relation.span}), not {arity}"
        )
    return None


def _kinds(
    relations: dict[str, Relation], rules: list[Rule], facts: list[Fact], told: set[str]
) -> list[Diagnostic]:
    """Inputs are told, never derived; what is given per formula is not told in files; what
    dkreason asks is derived."""
    errors = []
    for rule in rules:
        relation = relations[rule.head.predicate]
        if relation.kind in ("input", "given"):
            errors.append(
                _error(
                    f"{relation.name} is an {relation.kind} relation (declared at "
                    f"{relation.span}): rules may not derive it"
                    + (", though facts may tell it" if relation.kind == "input" else ""),
                    rule.head.span,
                )
            )
    for fact in facts:
        relation = relations[fact.predicate]
        if relation.kind == "given":
            errors.append(
                _error(
                    f"{relation.name} is given by dkreason while it asks a formula "
                    f"(declared at {relation.span}): no fact may tell it",
                    fact.span,
                )
            )
    derived = {rule.head.predicate for rule in rules} | told
    errors += [
        _error(
            f"the rules derive no {relation.name}/{relation.arity}, which dkreason asks for",
            relation.span,
        )
        for relation in relations.values()
        if relation.kind == "query" and relation.name not in derived  # a view may be empty
    ]
    return errors


def _variables(item: Literal | Comparison) -> Iterator[tuple[Var, Span]]:
    spans = item.spans or (item.span,) * (2 if isinstance(item, Comparison) else len(item.args))
    terms = (item.left, item.right) if isinstance(item, Comparison) else item.args
    for term, span in zip(terms, spans, strict=True):
        if isinstance(term, Var):
            yield term, span


def _show(term: Term) -> str:
    return term.name if isinstance(term, Var) else repr(term)


class Modes:
    """The argument patterns each relation is asked with, and whether its rules bind every
    variable in time under them (see the module docstring)."""

    def __init__(self, relations: dict[str, Relation], rules: Sequence[Rule]) -> None:
        self.relations = relations
        self.rules: dict[str, list[Rule]] = defaultdict(list)
        for rule in rules:
            self.rules[rule.head.predicate].append(rule)
        self._checked: dict[tuple[int, Mask], tuple[list[Diagnostic], list[Call]]] = {}
        self._shapes: dict[int, Shape] = {}
        self._asked: dict[Call, tuple[Diagnostic, ...]] = {}

    def entry_problems(self) -> list[Diagnostic]:
        """The variables bound too late when the policy is asked as dkreason asks it."""
        read = {
            b.predicate
            for rules in self.rules.values()
            for r in rules
            for b in r.body
            if isinstance(b, Literal)
        }
        entries = [
            name
            for name, relation in self.relations.items()
            if name in self.rules
            and (relation.kind in ("query", "view", "hook") or name not in read)
        ]
        found, seen = self._walk([(n, self._free(n)) for n in entries], set())
        unreached = [n for n in self.rules if not any(p == n for p, _ in seen)]
        more, _ = self._walk([(n, self._free(n)) for n in unreached], seen)
        return list(dict.fromkeys([*found, *more]))

    def problems(self, predicate: str, mask: Mask) -> tuple[Diagnostic, ...]:
        """What goes wrong if `predicate` is asked with the `mask`ed arguments bound."""
        call = (predicate, mask)
        if call not in self._asked:
            found, _ = self._walk([call], set())
            self._asked[call] = tuple(dict.fromkeys(found))
        return self._asked[call]

    def _free(self, name: str) -> Mask:
        return (False,) * self.relations[name].arity

    def _walk(self, todo: list[Call], seen: set[Call]) -> tuple[list[Diagnostic], set[Call]]:
        found: list[Diagnostic] = []
        while todo:
            call = todo.pop()
            if call in seen:
                continue
            seen.add(call)
            for rule in self.rules.get(call[0], ()):
                problems, calls = self._rule(rule, call[1])
                found += problems
                todo += calls
        return found, seen

    def _rule(self, rule: Rule, mask: Mask) -> tuple[list[Diagnostic], list[Call]]:
        key = (id(rule), mask)
        if key not in self._checked:
            if id(rule) not in self._shapes:
                self._shapes[id(rule)] = _shape(rule)
            self._checked[key] = bindings(rule, mask, self.rules, self._shapes[id(rule)])
        return self._checked[key]


Shape = tuple[Counter[str], tuple[tuple[tuple[Var, Span], ...], ...]]


def _shape(rule: Rule) -> Shape:
    """A rule's variables, read once: how often each occurs, and each body item's."""
    items = tuple(tuple(_variables(item)) for item in rule.body)
    uses = Counter(v.name for found in (tuple(_variables(rule.head)), *items) for v, _ in found)
    return uses, items


def bindings(
    rule: Rule, mask: Mask, derived: dict[str, list[Rule]], shape: Shape | None = None
) -> tuple[list[Diagnostic], list[Call]]:
    """A rule asked with the masked head arguments bound, body left to right: the variables it
    needs before anything binds them, and the derived relations it asks (with their masks)."""
    uses, variables = shape or _shape(rule)
    bound = {t.name for t, b in zip(rule.head.args, mask, strict=True) if b and isinstance(t, Var)}
    problems: list[Diagnostic] = []
    calls: list[Call] = []
    for item, found in zip(rule.body, variables, strict=True):
        free = [(v, s) for v, s in found if v.name not in bound]
        if isinstance(item, Comparison):
            if item.op == "==" and len(free) == 1 and item.left != item.right:
                bound.add(free[0][0].name)  # pyDatalog binds it to the other side
                continue
            text = f"{_show(item.left)} {item.op} {_show(item.right)}"
            problems += [
                _error(
                    f"{v.name} is compared in ({text}) before anything binds it: bind it in "
                    "a positive atom to the left",
                    span,
                )
                for v, span in free
            ]
        elif item.negated:  # a `_X` there alone means any value, as `_` does
            problems += [
                _error(
                    f"{v.name} in ~{item.predicate}(…) is bound by no positive atom to its "
                    "left: a negation only tests values already bound"
                    + (f" (name it _{v.name} if any value will do)" if uses[v.name] == 1 else ""),
                    span,
                )
                for v, span in free
                if not (v.name[0] == "_" and uses[v.name] == 1)
            ]
            if item.predicate in derived:  # asked with its "any value" arguments free
                calls.append(
                    (
                        item.predicate,
                        tuple(
                            not isinstance(t, Var) or uses[t.name] > 1 or t.name in bound
                            for t in item.args
                        ),
                    )
                )
        elif item.predicate in derived:
            calls.append(
                (
                    item.predicate,
                    tuple(not isinstance(t, Var) or t.name in bound for t in item.args),
                )
            )
        bound.update(v.name for v, _ in found)
    spans = rule.head.spans or (rule.head.span,) * len(rule.head.args)
    problems += [
        _error(
            f"{t.name} in the head of {rule.head.predicate} is bound by no positive atom of "
            "the body",
            span,
        )
        for t, span in zip(rule.head.args, spans, strict=True)
        if isinstance(t, Var) and t.name not in bound
    ]
    return problems, calls


def _strata(rules: Sequence[Rule]) -> list[Diagnostic]:
    """A relation that depends on its own negation, through however many rules: the cycle,
    each step with its rule's place."""
    edges: dict[str, list[tuple[str, Rule, Literal]]] = defaultdict(list)
    for rule in rules:
        for b in rule.body:
            if isinstance(b, Literal):
                edges[rule.head.predicate].append((b.predicate, rule, b))
    component = equivalent_sorts(
        edges, [(head, to) for head, out in edges.items() for to, _, _ in out]
    )
    errors, reported = [], set()
    for head, out in edges.items():
        for to, rule, lit in out:
            if not lit.negated or component.get(to) != component[head]:
                continue
            if component[head] in reported:
                continue
            reported.add(component[head])
            path = _path(edges, to, head, component)
            steps = [f"{rule.head.predicate} reads ~{to} ({rule.span.file}:{rule.span.line})"]
            steps += [
                f"{r.head.predicate} reads {t} ({r.span.file}:{r.span.line})" for t, r in path
            ]
            errors.append(
                _error(
                    f"negation cycle: {', '.join(steps)}; a relation may not depend on its "
                    "own negation",
                    lit.span,
                )
            )
    return errors


def _path(
    edges: dict[str, list[tuple[str, Rule, Literal]]],
    start: str,
    goal: str,
    component: dict[str, str],
) -> list[tuple[str, Rule]]:
    """The shortest chain of rules from `start` back to `goal` inside their component."""
    came: dict[str, tuple[str, Rule] | None] = {start: None}
    todo = [start]
    while todo and goal not in came:
        node = todo.pop(0)
        for to, rule, _ in edges.get(node, ()):
            if to not in came and component.get(to) == component[start]:
                came[to] = (node, rule)
                todo.append(to)
    path: list[tuple[str, Rule]] = []
    node = goal
    while came.get(node) is not None:
        previous, rule = came[node]  # type: ignore[misc]
        path.append((node, rule))
        node = previous
    return path[::-1] if start != goal else []


def given_readers(relations: dict[str, Relation], rules: Sequence[Rule]) -> dict[str, str]:
    """Each relation that reads, however indirectly, what dkreason gives only while it asks a
    formula, and the given relation it reads."""
    readers: dict[str, set[str]] = defaultdict(set)
    for rule in rules:
        for b in rule.body:
            if isinstance(b, Literal):
                readers[b.predicate].add(rule.head.predicate)
    source = {n: n for n, r in relations.items() if r.kind == "given"}
    todo = list(source)
    while todo:
        name = todo.pop()
        for reader in readers.get(name, ()):
            if reader not in source:
                source[reader] = source[name]
                todo.append(reader)
    return source


def _views(relations: dict[str, Relation], rules: Sequence[Rule]) -> list[Diagnostic]:
    """A view is computed once, at load: it may not read what is given per formula."""
    source = given_readers(relations, rules)
    return [
        _error(
            f"view {name} reads {source[name]}, which dkreason gives only while it asks a "
            f"formula (declared at {relations[source[name]].span}): a view is computed once, "
            "at load; declare it without a kind",
            relation.span,
        )
        for name, relation in relations.items()
        if relation.kind == "view" and name in source
    ]


def _warnings(
    files: Sequence[RuleFile],
    relations: dict[str, Relation],
    rules: Sequence[Rule],
    told: set[str],
    known: Known | None,
) -> list[Diagnostic]:
    out: list[Diagnostic] = []
    for f in files:
        for rule in f.rules:
            out += _variable_warnings(rule)
        if known is not None and not f.shipped:
            out += _constant_warnings(f, known)
    derived = {rule.head.predicate for rule in rules} | told
    read = {b.predicate for rule in rules for b in rule.body if isinstance(b, Literal)}
    own = [r for f in files if not f.shipped for r in f.relations]
    out += [
        _warning(f"{r.name} is declared, but no rule or fact derives it", r.span)
        for r in own
        if r.kind not in ("input", "given", "hook") and r.name not in derived
    ]
    out += [
        _warning(f"{r.name} is derived, but no rule reads it and dkreason does not ask it", r.span)
        for r in own
        if r.kind not in ("query", "hook") and r.name not in read and r.name in derived
    ]
    return out


def _variable_warnings(rule: Rule) -> list[Diagnostic]:
    """Names that are variables by mistake: lower-case ones, and ones used once in a positive
    atom of the body (once in the head, under negation or in a comparison is an error, or a
    value the rule's readers bind)."""
    uses: dict[str, list[Span]] = defaultdict(list)
    bound_once: set[str] = set()
    for item in (rule.head, *rule.body):
        for v, span in _variables(item):
            uses[v.name].append(span)
            if isinstance(item, Literal) and not item.negated and item is not rule.head:
                bound_once.add(v.name)
    out = []
    for name, spans in uses.items():
        if name[0].islower():
            out.append(
                _warning(
                    f"{name} is a variable (its name starts with a lower-case letter); "
                    f"write '{name}' for the constant",
                    spans[0],
                )
            )
        elif len(spans) == 1 and name in bound_once and not name.startswith("_"):
            out.append(
                _warning(
                    f"variable {name} occurs only once in the rule (name it _{name} if any "
                    "value will do)",
                    spans[0],
                )
            )
    return out


def _constants(f: RuleFile) -> Iterator[tuple[str, Span]]:
    """The string constants of a file's rules (a fact's own values are held by a fact)."""
    for rule in f.rules:
        for item in (rule.head, *rule.body):
            spans = item.spans or (item.span,) * (
                2 if isinstance(item, Comparison) else len(item.args)
            )
            terms: Iterable[Term] = (
                (item.left, item.right) if isinstance(item, Comparison) else item.args
            )
            for term, span in zip(terms, spans, strict=True):
                if isinstance(term, str):
                    yield term, span


def _constant_warnings(f: RuleFile, known: Known) -> list[Diagnostic]:
    out = []
    for value, span in dict.fromkeys(_constants(f)):
        if value == "" or value in KEYWORDS or known.holds(value):
            continue
        near = known.near(value)
        out.append(
            _warning(
                f"{value!r} occurs in no fact" + (f" (did you mean {near!r}?)" if near else ""),
                span,
            )
        )
    return out
