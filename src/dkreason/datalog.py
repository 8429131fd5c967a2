"""The one module that talks to pyDatalog.

pyDatalog keeps one engine per thread and its public `assert_fact`/`ask` re-parse Python
source on every call (~60 µs a fact, ~1 ms a query).  This wrapper gives each knowledge base its
own engine, asserts facts and asks queries through `pyEngine` directly (~6 µs a fact), and loads
rule files with errors that name the file and line.

Every relation is declared once, as Soufflé does: `.decl name(Column, …) [input|view|query]`
on a line of its own.  `input`: facts Python asserts; `view`: depends only on the knowledge
base, so `materialize()` computes it once and keeps its rows; `query`: Python asks it, so the
policy must derive it; no kind: derived at query time.  `check_policy()` refuses a rule that
names an undeclared relation or uses a wrong arity, with file:line and a "did you mean".

pyDatalog finds a lookup's facts by intersecting the index sets of its bound arguments in
argument order, starting from the first: with the platform bound, that is every fact of the
relation.  `_lookup` intersects from the smallest set instead, so a lookup costs what it
finds, not what the relation holds (at scale 100 of thesis chapter 7 that is 4× on checks).
"""

from __future__ import annotations

import ast
import difflib
import gc
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import RuleError, Span
from .inputs.files import read_text

Value = str | int
Row = tuple[Value, ...]

_BARE_UNDERSCORE = re.compile(r"(?<![\w'\"])_(?![\w])")


@dataclass(frozen=True, slots=True)
class Var:
    name: str


Term = Var | Value


@dataclass(frozen=True, slots=True)
class Literal:
    predicate: str
    args: tuple[Term, ...]
    negated: bool = False


@dataclass(frozen=True, slots=True)
class Comparison:
    op: str  # < <= > >= == !=
    left: Term
    right: Term


@dataclass(frozen=True, slots=True)
class Rule:
    """A clause as written in a rule file: what explanations replay and cite (file:line)."""

    head: Literal
    body: tuple[Literal | Comparison, ...]
    text: str
    span: Span


@dataclass(frozen=True, slots=True)
class Relation:
    """A declared relation: what Python and the rules agree on."""

    name: str
    columns: tuple[str, ...]
    kind: str  # 'input', 'view', 'query' or '' (derived at query time)
    span: Span

    @property
    def arity(self) -> int:
        return len(self.columns)

    def row(self, values: Sequence[Value]) -> dict[str, Value]:
        """A row of this relation with its columns named."""
        return dict(zip(self.columns, values, strict=True))


_DECL = re.compile(r"^\.decl\b(.*)$", re.M)
_DECL_BODY = re.compile(
    r"\s+([a-z_]\w*)\(\s*(\w+(?:\s*,\s*\w+)*)\s*\)\s*(input|view|query)?"
    r"\s*(?:#.*)?$"
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
        self.rules: list[Rule] = []
        self.texts: list[str] = []  # the rule files as read: what derived rows depend on
        self.schema: dict[str, Relation] = {}
        self._frozen: dict[str, list[object]] = {}  # materialized view → its rules
        self._consts: dict[Value, Any] = {}  # value → its pyEngine.Const

    def _activate(self) -> None:
        from pyDatalog import Logic

        if getattr(Logic.tl, "logic", None) is not self._logic:
            Logic(self._logic)
            self._logic = Logic(True)

    def load_file(self, path: Path) -> None:
        shown = os.path.relpath(path) if not os.path.relpath(path).startswith("..") else path
        self.load_text(read_text(path), str(shown))

    def load_text(self, text: str, file: str) -> None:
        for decl in _DECL.finditer(text):
            self._declare(decl.group(1), Span(file, text.count("\n", 0, decl.start()) + 1))
        rules = _clauses(_DECL.sub("", text), file)  # blanked, so lines keep their numbers
        self.texts.append(text)
        self._activate()
        for rule in rules:  # straight into the engine: pyParser would parse the text again
            _assert_rule(rule)
        self.rules += rules

    def _declare(self, text: str, span: Span) -> None:
        found = _DECL_BODY.fullmatch(text)
        if not found:
            raise RuleError(
                "expected `.decl name(Column, …)` and optionally input, view or query", span
            )
        name, columns, kind = found.group(1), found.group(2), found.group(3) or ""
        if name in self.schema:
            raise RuleError(f"{name} is declared twice (first at {self.schema[name].span})", span)
        self.schema[name] = Relation(name, tuple(c.strip() for c in columns.split(",")), kind, span)

    @property
    def views(self) -> dict[str, int]:
        return {r.name: r.arity for r in self.schema.values() if r.kind == "view"}

    def check_policy(self) -> None:
        """Every relation a rule names is declared, with its arity; every query is derived."""
        for rule in self.rules:
            for lit in (rule.head, *(b for b in rule.body if isinstance(b, Literal))):
                relation = self.schema.get(lit.predicate)
                if relation is None:
                    near = difflib.get_close_matches(lit.predicate, self.schema, 1)
                    hint = (
                        f" (did you mean {near[0]}/{self.schema[near[0]].arity}?)"
                        if near
                        else " (declare it with `.decl`)"
                    )
                    raise RuleError(
                        f"undeclared relation {lit.predicate}/{len(lit.args)}{hint}", rule.span
                    )
                if len(lit.args) != relation.arity:
                    raise RuleError(
                        f"{lit.predicate} has {relation.arity} columns "
                        f"({', '.join(relation.columns)}, declared at "
                        f"{relation.span}), not {len(lit.args)}",
                        rule.span,
                    )
        derived = {rule.head.predicate for rule in self.rules}
        for relation in self.schema.values():
            if relation.kind in ("query", "view") and relation.name not in derived:
                raise RuleError(
                    f"the rules derive no {relation.name}/{relation.arity}, which "
                    f"dkreason asks for",
                    relation.span,
                )

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
        terms = [
            pyEngine.Var(f"V{i}") if a is None else pyEngine.Const(a) for i, a in enumerate(args)
        ]
        with gc_paused():
            answer = pyEngine.Literal(predicate, terms).ask()
        return list(answer) if isinstance(answer, list) else []


def _assert_rule(rule: Rule) -> None:
    """The clause as pyParser would build it: `~name` for negation, the operator as the
    predicate of a comparison."""
    from pyDatalog import pyEngine

    def term(t: Term) -> object:
        return pyEngine.Var(t.name) if isinstance(t, Var) else pyEngine.Const(t)

    def literal(x: Literal | Comparison) -> object:
        if isinstance(x, Comparison):
            return pyEngine.Literal(x.op, [term(x.left), term(x.right)])
        return pyEngine.Literal(("~" if x.negated else "") + x.predicate, [term(a) for a in x.args])

    pyEngine.assert_(pyEngine.Clause(literal(rule.head), [literal(b) for b in rule.body]))


def _clauses(text: str, file: str) -> list[Rule]:
    """Each clause of a rule file with its line; rejects what pyDatalog would misread."""
    try:
        tree = ast.parse(text, file)
    except SyntaxError as exc:
        raise RuleError(f"not a rule: {exc.msg}", Span(file, exc.lineno or 0)) from None
    lines = text.splitlines()
    rules = []
    for node in tree.body:
        expr = node.value if isinstance(node, ast.Expr) else None
        if not (
            isinstance(expr, ast.Compare)
            and isinstance(expr.ops[0], ast.LtE)
            and isinstance(expr.left, ast.Call)
            and isinstance(expr.left.func, ast.Name)
        ):
            raise RuleError("expected a rule `head(...) <= body`", Span(file, node.lineno))
        source = "\n".join(lines[node.lineno - 1 : (node.end_lineno or node.lineno)])
        if len(_BARE_UNDERSCORE.findall(source)) > 1:
            raise RuleError(
                "bare `_` is one shared variable in pyDatalog; name each "
                "don't-care variable (_Field, _Arity, …)",
                Span(file, node.lineno),
            )
        span = Span(file, node.lineno)
        body = tuple(_body(expr.comparators[0], span))
        rules.append(Rule(_literal(expr.left, span), body, source.strip(), span))
    return rules


_OPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


def _body(node: ast.expr, span: Span) -> list[Literal | Comparison]:
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
        return _body(node.left, span) + _body(node.right, span)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Invert):
        lit = _literal(node.operand, span)
        return [Literal(lit.predicate, lit.args, negated=True)]
    if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _OPS:
        return [
            Comparison(
                _OPS[type(node.ops[0])], _term(node.left, span), _term(node.comparators[0], span)
            )
        ]
    return [_literal(node, span)]


def _literal(node: ast.expr, span: Span) -> Literal:
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
        raise RuleError("expected a literal `name(args)`", span)
    return Literal(node.func.id, tuple(_term(a, span) for a in node.args))


def _term(node: ast.expr, span: Span) -> Term:
    if isinstance(node, ast.Name):
        return Var(node.id)
    if isinstance(node, ast.Constant) and isinstance(node.value, str | int):
        return node.value
    raise RuleError(f"unsupported term {ast.unparse(node)!r}", span)
