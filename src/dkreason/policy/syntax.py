"""The rule language: what a rule file says, and where it says it.

A rule file is a pyDatalog program with Soufflé's declarations, one statement a line (a clause
may run on inside its parentheses):

    .decl name(Column, …) [input|given|view|query|hook]    every relation, declared once
    .input name(filename="rows.csv", delimiter=",", headers=true)    its facts from a table
    head(X, 'c') <= body(X, Y) & ~other(Y) & (X != 'd')    a rule
    name('a', 2)                                           a fact

Clauses are read with Python's parser (a pyDatalog program is Python), and every literal and
argument keeps its file:line:col: what the checker's messages and explanations cite.
"""

from __future__ import annotations

import ast
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import RuleError, Span

Value = str | int
Row = tuple[Value, ...]

KINDS = ("input", "given", "view", "query", "hook")
"""input: facts dkreason tells once loaded; given: facts dkreason tells while it asks one
formula; view: depends only on the knowledge base, computed once after loading; query:
dkreason asks it, so every policy derives it; hook: the shipped policy reads it (or dkreason
asks it) and rule files may derive it, empty unless they do; none: derived when asked."""

_NOWHERE = Span("<rule>")
_BARE_UNDERSCORE = re.compile(r"(?<![\w'\"])_(?![\w])")
_DIRECTIVE = re.compile(r"^\.(\w*)\b(.*)$", re.M)
_DECL_BODY = re.compile(
    r"\s+([a-z_]\w*)\(\s*(\w+(?:\s*,\s*\w+)*)\s*\)\s*(" + "|".join(KINDS) + r")?\s*(?:#.*)?$"
)
_INPUT_BODY = re.compile(r"\s+([a-z_]\w*)\s*(?:\((.*)\))?\s*(?:#.*)?$")
_OPTION = re.compile(r"\s*(\w+)\s*=\s*(\"(?:[^\"\\]|\\.)*\"|\w+)\s*(?:,|$)")


@dataclass(frozen=True, slots=True)
class Var:
    name: str


Term = Var | Value


@dataclass(frozen=True, slots=True)
class Literal:
    predicate: str
    args: tuple[Term, ...]
    negated: bool = False
    span: Span = field(default=_NOWHERE, compare=False)
    spans: tuple[Span, ...] = field(default=(), compare=False)  # each argument's


@dataclass(frozen=True, slots=True)
class Comparison:
    op: str  # < <= > >= == !=
    left: Term
    right: Term
    span: Span = field(default=_NOWHERE, compare=False)
    spans: tuple[Span, ...] = field(default=(), compare=False)  # left's and right's


Condition = Literal | Comparison


@dataclass(frozen=True, slots=True)
class Rule:
    """A clause as written in a rule file: what explanations replay and cite (file:line)."""

    head: Literal
    body: tuple[Condition, ...]
    text: str
    span: Span


@dataclass(frozen=True, slots=True)
class Fact:
    """A fact a rule file or a table tells, with where it tells it."""

    predicate: str
    row: Row
    span: Span


@dataclass(frozen=True, slots=True)
class Relation:
    """A declared relation: what Python and the rules agree on."""

    name: str
    columns: tuple[str, ...]
    kind: str  # one of KINDS, or '' (derived when asked)
    span: Span

    @property
    def arity(self) -> int:
        return len(self.columns)

    def row(self, values: Sequence[Value]) -> dict[str, Value]:
        """A row of this relation with its columns named."""
        return dict(zip(self.columns, values, strict=True))


@dataclass(frozen=True, slots=True)
class Table:
    """`.input name(filename=…, delimiter=…, headers=…)`: a relation's facts in a CSV or TSV
    file, relative to the rule file (default `name.facts`, tab-separated as in Soufflé)."""

    relation: str
    path: Path
    file: str  # as messages show it
    delimiter: str
    headers: bool
    span: Span


@dataclass(frozen=True, slots=True)
class RuleFile:
    file: str  # as messages show it
    text: str
    relations: tuple[Relation, ...]
    rules: tuple[Rule, ...]
    facts: tuple[Fact, ...]
    tables: tuple[Table, ...]
    shipped: bool = False  # one of dkreason's own (rules/)


def parse_rules(
    text: str, file: str, folder: Path | None = None, shipped: bool = False
) -> RuleFile:
    """A rule file's declarations, tables, rules and facts; the first thing it cannot read is
    a RuleError naming file:line:col.  `folder`: where its tables are (default: none may be
    named)."""
    relations: list[Relation] = []
    tables: list[Table] = []
    for directive in _DIRECTIVE.finditer(text):
        span = Span(file, text.count("\n", 0, directive.start()) + 1)  # a declaration is a line
        name, rest = directive.group(1), directive.group(2)
        if name == "decl":
            relations.append(_declaration(rest, span))
        elif name == "input":
            tables.append(_table(rest, span, folder))
        else:
            raise RuleError(f"unknown directive .{name} (expected .decl or .input)", span)
    # the directives blanked, so lines keep their numbers
    rules, facts = _clauses(_DIRECTIVE.sub("", text), file)
    return RuleFile(
        file, text, tuple(relations), tuple(rules), tuple(facts), tuple(tables), shipped
    )


def _declaration(text: str, span: Span) -> Relation:
    found = _DECL_BODY.fullmatch(text)
    if not found:
        raise RuleError(f"expected `.decl name(Column, …)` and optionally {', '.join(KINDS)}", span)
    name, columns, kind = found.group(1), found.group(2), found.group(3) or ""
    return Relation(name, tuple(c.strip() for c in columns.split(",")), kind, span)


def _table(text: str, span: Span, folder: Path | None) -> Table:
    found = _INPUT_BODY.fullmatch(text)
    if not found:
        raise RuleError('expected `.input name(filename="rows.csv")`', span)
    name, options_text = found.group(1), found.group(2) or ""
    options: dict[str, str] = {}
    at = 0
    while at < len(options_text.rstrip()):
        option = _OPTION.match(options_text, at)
        if option is None:
            raise RuleError(f"cannot read the options of .input {name}: {options_text!r}", span)
        key, value = option.group(1), option.group(2)
        options[key] = ast.literal_eval(value) if value.startswith('"') else value
        at = option.end()
    unknown = sorted(set(options) - {"IO", "filename", "delimiter", "headers"})
    if unknown or options.get("IO", "file") != "file":
        raise RuleError(
            f".input {name}: unknown option {(unknown or ['IO'])[0]} (expected filename, "
            "delimiter, headers)",
            span,
        )
    if folder is None:
        raise RuleError(f".input {name}: a table is read only from a rule file", span)
    filename = options.get("filename", f"{name}.facts")
    path = folder / filename
    delimiter = options.get("delimiter", "," if path.suffix == ".csv" else "\t")
    if len(delimiter) != 1:
        raise RuleError(f".input {name}: the delimiter must be one character", span)
    headers = options.get("headers", "false")
    if headers not in ("true", "false"):
        raise RuleError(f".input {name}: headers must be true or false", span)
    shown = os.path.normpath(os.path.join(os.path.dirname(span.file), filename))
    return Table(name, path, shown, delimiter, headers == "true", span)


def _clauses(text: str, file: str) -> tuple[list[Rule], list[Fact]]:
    """Each clause of a rule file with its place; rejects what pyDatalog would misread."""
    try:
        tree = ast.parse(text, file)
    except SyntaxError as exc:
        raise RuleError(
            f"not a rule: {exc.msg}", Span(file, exc.lineno or 0, exc.offset or 0)
        ) from None
    at = _Positions(text, file)
    rules, facts = [], []
    for node in tree.body:
        expr = node.value if isinstance(node, ast.Expr) else None
        span = at(node)
        if isinstance(expr, ast.Call):
            facts.append(_fact(expr, at))
            continue
        if not (
            isinstance(expr, ast.Compare)
            and len(expr.ops) == 1
            and isinstance(expr.ops[0], ast.LtE)
            and isinstance(expr.left, ast.Call)
        ):
            raise RuleError("expected a rule `head(...) <= body` or a fact `name(...)`", span)
        source = at.source(node)
        if len(_BARE_UNDERSCORE.findall(source)) > 1:
            raise RuleError(
                "bare `_` is one shared variable in pyDatalog; name each "
                "don't-care variable (_Field, _Arity, …)",
                span,
            )
        body = tuple(_body(expr.comparators[0], at))
        rule_span = Span(file, node.lineno)  # a rule is cited by its line
        rules.append(Rule(_literal(expr.left, at), body, source.strip(), rule_span))
    return rules, facts


class _Positions:
    """file:line:col of a node (Python counts columns in UTF-8 bytes; messages in characters)."""

    def __init__(self, text: str, file: str) -> None:
        self.lines, self.file = text.splitlines(), file
        self.ascii = text.isascii()  # then a byte is a character

    def __call__(self, node: ast.expr | ast.stmt) -> Span:
        if self.ascii:
            return Span(self.file, node.lineno, node.col_offset + 1)
        line = self.lines[node.lineno - 1] if node.lineno <= len(self.lines) else ""
        column = len(line.encode()[: node.col_offset].decode(errors="ignore")) + 1
        return Span(self.file, node.lineno, column)

    def source(self, node: ast.stmt) -> str:
        return "\n".join(self.lines[node.lineno - 1 : (node.end_lineno or node.lineno)])


def _fact(node: ast.Call, at: _Positions) -> Fact:
    literal = _literal(node, at)
    for arg, span in zip(literal.args, literal.spans, strict=True):
        if isinstance(arg, Var):
            raise RuleError(
                f"{arg.name} is a variable, and a fact holds constants only (a rule "
                "needs `<= body`; a constant is quoted: 'name')",
                span,
            )
    told = Span(literal.span.file, literal.span.line)  # a fact is cited by its line
    return Fact(literal.predicate, literal.args, told)  # type: ignore[arg-type]


_OPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


def _body(node: ast.expr, at: _Positions) -> list[Condition]:
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
        return _body(node.left, at) + _body(node.right, at)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Invert):
        lit = _literal(node.operand, at)
        return [Literal(lit.predicate, lit.args, True, at(node), lit.spans)]
    if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _OPS:
        left, right = node.left, node.comparators[0]
        return [
            Comparison(
                _OPS[type(node.ops[0])],
                _term(left, at),
                _term(right, at),
                at(node),
                (at(left), at(right)),
            )
        ]
    return [_literal(node, at)]


def _literal(node: ast.expr, at: _Positions) -> Literal:
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)) or node.keywords:
        raise RuleError("expected a literal `name(args)`", at(node))
    return Literal(
        node.func.id,
        tuple(_term(a, at) for a in node.args),
        span=at(node),
        spans=tuple(at(a) for a in node.args),
    )


def _term(node: ast.expr, at: _Positions) -> Term:
    if isinstance(node, ast.Name):
        return Var(node.id)
    if isinstance(node, ast.Constant) and isinstance(node.value, str | int):
        return node.value
    if (
        isinstance(node, ast.UnaryOp)
        and isinstance(node.op, ast.USub)
        and isinstance(node.operand, ast.Constant)
        and type(node.operand.value) is int
    ):
        return -node.operand.value
    raise RuleError(f"unsupported term {ast.unparse(node)!r}", at(node))


def parse_query(text: str, file: str = "<query>") -> tuple[Condition, ...]:
    """A query: a rule body (`p(X, 'c') & ~q(X)`), or one literal of the reader's
    relevant_topic/4 whose arguments and filter may be written as tuples."""
    try:
        tree = ast.parse(text.strip(), file, mode="eval")
    except SyntaxError as exc:
        raise RuleError(
            f"not a query: {exc.msg}", Span(file, exc.lineno or 0, exc.offset or 0)
        ) from None
    at = _Positions(text.strip(), file)
    return tuple(_body(_tuples_as_terms(tree.body), at))


_TUPLE = "\0tuple:"  # a query's tuple term, held as one constant until the query reads it


def tuple_constant(values: tuple[Value, ...]) -> str:
    """A tuple of a query's arguments as the one constant its literal holds."""
    return _TUPLE + json.dumps(values)


def read_tuple(value: Term) -> tuple[Value, ...] | None:
    """The tuple a query's constant holds, if it holds one."""
    if isinstance(value, str) and value.startswith(_TUPLE):
        return tuple(json.loads(value[len(_TUPLE) :]))
    return None


def _tuples_as_terms(node: ast.expr) -> ast.expr:
    """Tuples and lists of constants in a query's arguments as one constant each, so the
    literal reads like any other (the reader's relevant_topic/4 takes its arguments and its
    filter as tuples)."""
    for call in ast.walk(node):
        if not isinstance(call, ast.Call):
            continue
        for i, arg in enumerate(call.args):
            if isinstance(arg, ast.Tuple | ast.List):
                values = tuple(
                    e.value
                    for e in arg.elts
                    if isinstance(e, ast.Constant) and isinstance(e.value, str | int)
                )
                if len(values) != len(arg.elts):
                    raise RuleError(
                        f"a tuple holds constants only: {ast.unparse(arg)}",
                        Span("<query>", arg.lineno, arg.col_offset + 1),
                    )
                call.args[i] = ast.copy_location(ast.Constant(tuple_constant(values)), arg)
    return node
