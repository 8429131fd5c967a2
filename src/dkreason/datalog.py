"""The one module that talks to pyDatalog.

pyDatalog keeps one engine per thread and its public `assert_fact`/`ask` re-parse Python
source on every call (~60 µs a fact, ~1 ms a query).  This wrapper gives each knowledge base its
own engine, asserts facts and asks queries through `pyEngine` directly (~6 µs a fact), and loads
rule files (dkreason.policy reads and checks them) as one policy or not at all.

Every relation is declared once, as Soufflé does: `.decl name(Column, …) [kind]` on a line of
its own (policy/syntax.py lists the kinds).  A `view` depends only on the knowledge base, so
`materialize()` computes it once and keeps its rows; a `query` is asked by Python, so the
policy must derive it.  A relation that nothing derives or tells is empty: a rule's negation
of it always holds and is left out of the engine's clause (an unused hook costs nothing).

pyDatalog finds a lookup's facts by intersecting the index sets of its bound arguments in
argument order, starting from the first: with the platform bound, that is every fact of the
relation.  `_lookup` intersects from the smallest set instead, so a lookup costs what it
finds, not what the relation holds (at scale 100 of thesis chapter 7 that is 4× on checks).
"""

from __future__ import annotations

import gc
from collections import defaultdict
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from .errors import RuleError, Span
from .policy.check import Diagnostic, Known, Modes, check, declared
from .policy.syntax import (
    Comparison,
    Condition,
    Fact,
    Literal,
    Relation,
    Row,
    Rule,
    RuleFile,
    Term,
    Value,
    Var,
)


@contextmanager
def gc_paused() -> Iterator[None]:
    """Python's cyclic collector, paused.  Loading a knowledge base builds a large heap of small
    objects; left running, the collector scans that growing heap again and again (a third of
    the load time at 500 specs).  Nothing is lost: collection resumes afterwards."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


_NO_BODY: list[object] = []  # every fact's body: nothing in pyDatalog adds to a fact's body


def _lookup(literal: object) -> list[object]:
    """pyEngine.relevant_clauses: the predicate's rules, then the facts that agree with every
    bound argument (its index is keyed by the constants themselves, so no collisions; a value
    only one fact holds maps to that fact, not to a set of one: see `assert_rows`)."""
    pred = literal.pred  # type: ignore[attr-defined]
    index = pred.index
    buckets = []
    for i, t in enumerate(literal.terms):  # type: ignore[attr-defined]
        if t.is_const():
            bucket = index[i].get(t.id)
            if bucket is None:
                return list(pred.clauses.values())
            buckets.append(bucket)
    if not buckets:
        return list(pred.db.values())
    single = next((b for b in buckets if type(b) is not set), None)
    if single is not None:  # the one fact holding that value, if it agrees with the rest
        agrees = all(b is single if type(b) is not set else single in b for b in buckets)
        return [*pred.clauses.values(), single] if agrees else list(pred.clauses.values())
    buckets.sort(key=len)
    found = buckets[0]
    for bucket in buckets[1:]:
        if not found:
            break
        found = found.intersection(bucket)
    return [*pred.clauses.values(), *found]


class Datalog:
    """One engine.  Relations declared `view` depend only on the knowledge base (not on a
    formula), so `materialize()` computes them once and keeps their rows as facts; pyDatalog
    would otherwise re-derive them on every query."""

    def __init__(self) -> None:
        from pyDatalog import Logic, pyEngine

        pyEngine.relevant_clauses = _lookup
        self._logic = Logic()  # a fresh engine, current in this thread
        self.files: list[RuleFile] = []
        self.rules: list[Rule] = []
        self.texts: list[str] = []  # the rule files as read, and their facts: what rows depend on
        self.schema: dict[str, Relation] = {}
        self.told: dict[Row, Span] = {}  # (relation, *values) of each fact a file tells → where
        self.modes = Modes({}, [])
        self._frozen: dict[str, list[object]] = {}  # materialized view → its rules
        self._consts: dict[Value, Any] = {}  # value → its pyEngine.Const
        self._derived: set[str] = set()  # the relations rules derive or files tell
        self._clauses: dict[Rule, object] = {}  # each rule's clause in the engine
        self._pruned: dict[str, set[Rule]] = defaultdict(set)  # empty relation → rules negating it
        # relations empty for want of facts (no input rows, an empty view, nothing to derive
        # them from): a rule that needs one holds nowhere, a negation of one always holds
        self._void: frozenset[str] = frozenset()
        # given relations without rows now (`degraded` while nothing is set aside): a rule
        # needing one is asked with it, but a negation of one holds, so it is left out
        self._bare: frozenset[str] = frozenset()
        self._negated_given: set[str] = set()  # the given relations a rule negates (watched)
        self._void_key: tuple[bool, ...] | None = None

    def _activate(self) -> None:
        from pyDatalog import Logic

        if getattr(Logic.tl, "logic", None) is not self._logic:
            Logic(self._logic)
            self._logic = Logic(True)

    def load(self, files: Sequence[RuleFile], known: Known | None = None) -> list[Diagnostic]:
        """The files' relations, rules and facts, checked as one policy with those loaded
        before (dkreason.policy.check): all of them, or, on an error, none (the first error is
        raised and the engine is as it was).  Returns the warnings."""
        found = check([*self.files, *files], known)
        errors = [d for d in found if d.severity == "error"]
        if errors:
            raise RuleError(errors[0].message, errors[0].span)
        self.files += files
        self.schema, _ = declared(self.files)
        rules = [rule for f in files for rule in f.rules]
        self.rules += rules
        self.modes = Modes(self.schema, self.rules)
        self._negated_given = {
            b.predicate
            for rule in self.rules
            for b in rule.body
            if isinstance(b, Literal) and b.negated and self.schema[b.predicate].kind == "given"
        }
        facts = [fact for f in files for fact in f.facts]
        self.texts += [f.text for f in files] + [repr([(x.predicate, x.row) for x in facts])]
        self._activate()
        filled = {r.head.predicate for r in rules} | {x.predicate for x in facts}
        self._derived |= filled
        for name in filled & self._pruned.keys():  # its negation no longer always holds
            for rule in self._pruned.pop(name):
                self._assert(rule)
        for rule in rules:  # straight into the engine: pyParser would parse the text again
            self._assert(rule)
        by_relation: dict[str, list[Fact]] = defaultdict(list)
        for fact in facts:
            by_relation[fact.predicate].append(fact)
            self.told.setdefault((fact.predicate, *fact.row), fact.span)
        for name, told in by_relation.items():
            self.assert_rows(name, [fact.row for fact in told])
        return [d for d in found if d.severity == "warning"]

    def derives(self, name: str) -> bool:
        """Whether a rule derives the relation or a file tells it facts (what a hook is
        asked for only then)."""
        return name in self._derived

    def _empty(self, name: str) -> bool:
        """Nothing derives or tells the relation, nor can: it is and stays empty."""
        return self.schema[name].kind not in ("input", "given") and not self.derives(name)

    def _assert(self, rule: Rule) -> None:
        """The rule into the engine, or in place of its clause there (held aside, if it is a
        frozen view's): without its negations of relations that are empty."""
        from pyDatalog import pyEngine

        void, bare = self._void, self._bare
        pruned = [
            b.predicate
            for b in rule.body
            if isinstance(b, Literal)
            and b.negated
            and (self._empty(b.predicate) or b.predicate in void or b.predicate in bare)
        ]
        clause = _clause(rule, pruned)
        old = self._clauses.get(rule)
        frozen = self._frozen.get(rule.head.predicate, [])
        if old is not None and old in frozen:
            frozen[frozen.index(old)] = clause
        else:
            if old is not None:
                pyEngine.retract(old)
            if any(
                isinstance(b, Literal) and not b.negated and b.predicate in void for b in rule.body
            ):
                self._clauses.pop(rule, None)  # it holds nowhere: out of the engine
                return
            pyEngine.assert_(clause)
        self._clauses[rule] = clause
        for name in pruned:
            self._pruned[name].add(rule)

    def _refresh(self) -> None:
        """Rules out of the engine while they need a relation that is empty for want of
        facts (an input without rows, a materialized view without rows, or one derived only
        from such), and their negations of it left out: a policy's rules over facts nobody
        told (declared stream quality in the thesis' scenarios) cost a query nothing.  Asked
        before each query; recomputed when an input or a view gains or loses its last row."""
        from pyDatalog import Logic

        db = Logic.tl.logic.Db
        watched = [
            r
            for r in self.schema.values()
            if r.kind == "input" or r.name in self._frozen or r.name in self._negated_given
        ]
        key = tuple(
            (pred := db.get(f"{r.name}/{r.arity}")) is not None and len(pred.db) > len(pred.clauses)
            for r in watched
        )
        if key == self._void_key:
            return
        self._void_key = key
        live = {r.name for r, rows in zip(watched, key, strict=True) if rows}
        live |= {r.name for r in self.schema.values() if r.kind == "given"}
        live |= {t[0] for t in self.told if isinstance(t[0], str)}
        rules = [r for r in self.rules if r.head.predicate not in self._frozen]
        grown = True
        while grown:  # the least fixpoint: a relation lives if a rule of it can hold
            grown = False
            for rule in rules:
                head = rule.head.predicate
                if head not in live and all(
                    b.predicate in live
                    for b in rule.body
                    if isinstance(b, Literal) and not b.negated
                ):
                    live.add(head)
                    grown = True
        void = frozenset(self.schema) - live
        bare = frozenset(
            r.name for r, rows in zip(watched, key, strict=True) if r.kind == "given" and not rows
        )
        changed = (void ^ self._void) | (bare ^ self._bare)
        self._void, self._bare = void, bare
        for rule in self.rules:
            if any(isinstance(b, Literal) and b.predicate in changed for b in rule.body):
                self._assert(rule)

    @property
    def views(self) -> dict[str, int]:
        return {r.name: r.arity for r in self.schema.values() if r.kind == "view"}

    @contextmanager
    def given(self, inputs: dict[str, list[Row]]) -> Iterator[None]:
        """These input facts, for the queries inside the block: how a formula asks the rules
        (asserted on entry, retracted on exit, whatever happens)."""
        for name, rows in inputs.items():
            self.assert_rows(name, rows)
        try:
            yield
        finally:
            for name, rows in inputs.items():
                self.retract_rows(name, rows)

    def ask(self, predicate: str, inputs: dict[str, list[Row]], *args: Value | None) -> list[Row]:
        """`query` with these input facts given."""
        with self.given(inputs):
            return self.query(predicate, *args)

    def assert_rows(self, predicate: str, rows: Iterable[Sequence[Value]]) -> None:
        """What `pyEngine.assert_` does for a fact, for many at once: the predicate's tables
        are looked up once, not per fact, and facts share their constants (one `Const` per
        value, not per use) and their empty body, and a value only one fact holds (an
        object's name, a topic's) maps to that fact in the index, not to a set of one.  ~2 µs
        and ~0.6 KB a fact, not ~5 µs and ~1.2 KB.  Facts leave through `retract_rows`, which
        knows this index (pyEngine.retract does not)."""
        from pyDatalog.pyEngine import Clause, Const, Literal, insert

        rows = list(rows)
        if not rows:
            return
        self._activate()
        pred = Literal(predicate, [Const(v) for v in rows[0]]).pred  # interned; sets prearity
        insert(pred)
        db, index, name, consts, body = pred.db, pred.index, pred.id, self._consts, _NO_BODY
        for row in rows:
            terms = [consts.get(v) or consts.setdefault(v, Const(v)) for v in row]
            key = ((name, *[t.id for t in terms]),)  # Clause.get_id(); one copy of each value
            if key in db:
                continue
            clause = Clause(Literal(pred, terms), body)
            clause.id = key
            db[key] = clause
            for column, term in zip(index, terms, strict=True):
                found = column.get(term.id)
                if found is None:  # held by this fact alone: the fact itself, not a set
                    column[term.id] = clause
                elif type(found) is set:
                    found.add(clause)
                else:
                    column[term.id] = {found, clause}

    def retract_rows(self, predicate: str, rows: Iterable[Sequence[Value]]) -> None:
        """Facts out again, from the tables `assert_rows` keeps (a value's index entry is the
        one fact holding it, or a set)."""
        from pyDatalog import Logic

        self._activate()
        rows = list(rows)
        pred = Logic.tl.logic.Db.get(f"{predicate}/{len(rows[0])}") if rows else None
        if pred is None:
            return
        db, index = pred.db, pred.index
        for row in rows:
            clause = db.pop(((pred.id, *row),), None)
            if clause is None:
                continue
            for column, v in zip(index, row, strict=True):
                found = column[v]
                if found is clause:
                    del column[v]
                    continue
                found.discard(clause)
                if len(found) == 1:
                    column[v] = next(iter(found))

    def materialize(self) -> None:
        """Replace each declared view's rules by its rows (call `thaw` before the facts it
        depends on change).  Views are computed in dependency order, each frozen before the
        next, so no view is derived again inside another."""
        for name in self._view_order():
            if name not in self._frozen:
                self._freeze(name, self.query(name, *[None] * self.views[name]))

    def restore(self, views: dict[str, list[Row]]) -> None:
        """Freeze the views with rows an earlier `materialize` computed from the same facts
        and rules (`frozen()`): what a cached knowledge base skips.  `views` is emptied as
        they go in (each view's rows are then held once, by the engine)."""
        for name in list(views):
            self._freeze(name, views.pop(name))

    def rows(self, name: str) -> list[Row]:
        """Every row of a relation: a materialized view's read back as stored, anything else
        (a thawed view too) asked."""
        if name in self._frozen:
            return self._rows(name)
        return self.query(name, *[None] * self.schema[name].arity)

    def frozen(self) -> dict[str, list[Row]]:
        """The rows of every materialized view."""
        return {name: self._rows(name) for name in self._frozen}

    def _rows(self, name: str) -> list[Row]:
        """A relation's facts, read back from the engine (not kept twice)."""
        from pyDatalog import Logic

        self._activate()
        pred = Logic.tl.logic.Db.get(f"{name}/{self.schema[name].arity}")
        return (
            []
            if pred is None
            else [tuple(t.id for t in c.head.terms) for c in pred.db.values() if not c.body]
        )

    def _freeze(self, name: str, rows: list[Row]) -> None:
        from pyDatalog import Logic, pyEngine

        self._activate()
        pred = Logic.tl.logic.Db.get(f"{name}/{self.views[name]}")
        rules = list(pred.clauses.values()) if pred is not None else []
        for clause in rules:  # Pred.reset_clauses() mutates what it iterates over
            pyEngine.retract(clause)
        self.assert_rows(name, rows)
        self._frozen[name] = rules

    def sizes(self) -> dict[str, tuple[str, int]]:
        """Each stored relation (input facts and materialized views): its kind and rows."""
        from pyDatalog import Logic

        self._activate()
        db = Logic.tl.logic.Db
        out: dict[str, tuple[str, int]] = {}
        for r in self.schema.values():
            pred = db.get(f"{r.name}/{r.arity}")
            if r.kind in ("input", "view") and pred is not None:
                out[r.name] = (r.kind, len(pred.db) - len(pred.clauses))
        return out

    def _reads(self) -> dict[str, set[str]]:
        """Each derived predicate and the predicates its rules' bodies name."""
        reads: dict[str, set[str]] = {}
        for rule in self.rules:
            reads.setdefault(rule.head.predicate, set()).update(
                b.predicate for b in rule.body if isinstance(b, Literal)
            )
        return reads

    def _view_order(self) -> list[str]:
        """The views, each after every view its rules reach."""
        reads = self._reads()
        order: list[str] = []
        seen: set[str] = set()

        def visit(pred: str) -> None:
            if pred in seen:
                return
            seen.add(pred)
            for used in sorted(reads.get(pred, ())):
                visit(used)
            if pred in self.views:
                order.append(pred)

        for view in self.views:
            visit(view)
        return order

    def thaw(self, changed: Iterable[str]) -> list[str]:
        """Put back the rules of the views whose rules reach a `changed` predicate (their rows
        go), so they follow the changed facts; the other views stay as they are.  Returns the
        views thawed."""
        from pyDatalog import pyEngine

        readers: dict[str, set[str]] = {}
        for head, body in self._reads().items():
            for pred in body:
                readers.setdefault(pred, set()).add(head)
        stale, todo = set(changed), list(changed)
        while todo:  # everything derived, however indirectly, from a changed predicate
            for reader in readers.get(todo.pop(), ()):
                if reader not in stale:
                    stale.add(reader)
                    todo.append(reader)
        thawed = [v for v in self._frozen if v in stale]
        for name in thawed:
            self.retract_rows(name, self._rows(name))
            rules = self._frozen.pop(name)
            for clause in rules:
                pyEngine.assert_(clause)
        return thawed

    def query(self, predicate: str, *args: Value | None) -> list[Row]:
        """All rows of `predicate` matching `args` (None = any value)."""
        from pyDatalog import pyEngine

        relation = self.schema.get(predicate)
        if relation is not None and len(args) != relation.arity:
            raise TypeError(f"{predicate} has {relation.arity} columns, asked with {len(args)}")
        self._activate()
        self._refresh()
        if relation is not None and f"{predicate}/{relation.arity}" not in self._logic.Db:
            return []  # declared, and neither derived nor told: empty
        terms = [
            pyEngine.Var(f"V{i}") if a is None else pyEngine.Const(a) for i, a in enumerate(args)
        ]
        with gc_paused():
            answer = pyEngine.Literal(predicate, terms).ask()
        return list(answer) if isinstance(answer, list) else []

    def solve(self, body: Sequence[Condition], variables: Sequence[str]) -> list[Row]:
        """The values of `variables` for which every condition of `body` holds: a question of
        several conditions, asked through a rule made for it and retracted after (the caller
        checks that it binds its variables in time)."""
        from pyDatalog import pyEngine

        self._activate()
        self._refresh()
        for lit in body:
            relation = self.schema.get(lit.predicate) if isinstance(lit, Literal) else None
            if relation is not None and f"{relation.name}/{relation.arity}" not in self._logic.Db:
                pyEngine.insert(pyEngine.Literal(relation.name, [0] * relation.arity).pred)
        head = Literal("dkreason_query_", tuple(map(Var, variables)) or (1,))
        clause = _clause(Rule(head, tuple(body), "", Span("<query>")), ())
        pyEngine.assert_(clause)
        try:
            with gc_paused():
                answer = _literal(head).ask()
        finally:
            pyEngine.retract(clause)
        rows = list(answer) if isinstance(answer, list) else []
        return rows if variables else [()] * bool(rows)

    def askable(self, predicate: str, args: Sequence[Value | None]) -> tuple[Diagnostic, ...]:
        """What goes wrong if `predicate` is asked with these arguments (None = free): the
        variables its rules would need before anything binds them (none: it may be asked)."""
        return self.modes.problems(predicate, tuple(a is not None for a in args))


def _term(t: Term) -> object:
    from pyDatalog import pyEngine

    return pyEngine.Var(t.name) if isinstance(t, Var) else pyEngine.Const(t)


def _literal(x: Condition) -> Any:
    """A condition as pyParser would build it: `~name` for negation, the operator as the
    predicate of a comparison."""
    from pyDatalog import pyEngine

    if isinstance(x, Comparison):
        return pyEngine.Literal(x.op, [_term(x.left), _term(x.right)])
    return pyEngine.Literal(("~" if x.negated else "") + x.predicate, [_term(a) for a in x.args])


def _clause(rule: Rule, pruned: Sequence[str]) -> object:
    """The rule's clause, without its negations of the `pruned` relations; a relation it
    negates is known to the engine, empty as declared, though nothing tells it yet."""
    from pyDatalog import Logic, pyEngine

    body = [
        _literal(b)
        for b in rule.body
        if not (isinstance(b, Literal) and b.negated and b.predicate in pruned)
    ]
    for lit in body:
        base = getattr(lit.pred, "base_pred", None)
        if base is not None and base.id not in Logic.tl.logic.Db:
            pyEngine.insert(base)
    return pyEngine.Clause(_literal(rule.head), body)
