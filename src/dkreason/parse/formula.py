"""MTL formulas (mtl.lark) → a small frozen AST, and the features a formula needs.

One grammar serves the matcher (which only needs the features) and the progression engine
(which needs everything).  Interval bounds are exact `Fraction`s of seconds, so `250ms` is 1/4.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from functools import lru_cache
from pathlib import Path
from typing import Any

from lark import Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput

from ..errors import ParseError, Span
from ..inputs.files import read_text
from ..inputs.numbers import UNITS, decimal
from ..model import Arg, FeatureKey, FeatureRef
from .grammar import lalr

FILE = "<formula>"
MAX_NUMBER = 100  # characters of a number literal


@dataclass(frozen=True, slots=True)
class Interval:
    lo: Fraction
    hi: Fraction | None  # None: unbounded

    def __str__(self) -> str:
        return f"[{self.lo}, {'oo' if self.hi is None else self.hi}]"


ANY = Interval(Fraction(0), None)


# ---- expressions (numeric or boolean values of features) ------------------------------------


@dataclass(frozen=True, slots=True)
class Num:
    value: int | float


@dataclass(frozen=True, slots=True)
class Ref:
    feature: FeatureRef


@dataclass(frozen=True, slots=True)
class Arith:
    op: str  # + - * /
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Unary:
    """-x, abs(x) or sqrt(x)."""

    op: str  # - abs sqrt
    arg: Expr


@dataclass(frozen=True, slots=True)
class Func:
    """min(x, y), max(x, y) or hypot(x, y)."""

    op: str  # min max hypot
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Sampled:
    """A term over a feature's samples: `prev(X)` (its value at its previous sample),
    `delta(X)`, `rate(X)` (per second of valid time between the two), `age(X)` (seconds
    since its last sample).  The state carries each as a value of its own (`term_key`), so
    whoever makes states (the stream processor, or the progressor from a state file) keeps
    two samples a feature, no more."""

    op: str  # prev delta rate age
    arg: Ref


@dataclass(frozen=True, slots=True)
class Str:
    """A string constant: compared with == or != to a string field."""

    value: str


Expr = Num | Str | Ref | Arith | Unary | Func | Sampled


# ---- formulas --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class BoolConst:
    value: bool


@dataclass(frozen=True, slots=True)
class Atom:
    feature: FeatureRef


@dataclass(frozen=True, slots=True)
class Observed:
    """`observed(X)`: X has a value now.  Two-valued, never unknown, so startup and dropout
    can be judged (`eventually[0, 5] observed(X)` from `--start`)."""

    feature: FeatureRef


@dataclass(frozen=True, slots=True)
class Fresh:
    """`fresh(X, 500ms)`: X's last sample is at most `limit` seconds old (`age(X) <= limit`,
    ages being seconds whatever the stream's unit).  Two-valued: false before X's first
    sample."""

    arg: Ref
    limit: Fraction


@dataclass(frozen=True, slots=True)
class Compare:
    op: str  # < <= > >= == !=
    left: Expr
    right: Expr


MIRRORED = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}
"""Each comparison as it reads the other way round (`c < X` is `X > c`)."""


def oriented(c: Compare, kind: type | tuple[type, ...]) -> tuple[Any, str, Expr] | None:
    """The comparison read with a `kind` of term on its left (`60 < Speed[car1]` as
    `Speed[car1] > 60`): (that term, op, the other side); None when neither side is one."""
    if isinstance(c.left, kind):
        return c.left, c.op, c.right
    if isinstance(c.right, kind):
        return c.right, MIRRORED[c.op], c.left
    return None


def age_bound(c: Compare) -> tuple[Sampled, str, Fraction] | None:
    """`age(X) op d` with a number d ≥ 0, either way round (as read with the age on the
    left): what a deadline can be made of; None for any other comparison."""
    found = oriented(c, Sampled)
    if found is None or found[0].op != "age" or not isinstance(found[2], Num):
        return None
    limit = Fraction(found[2].value)
    return (found[0], found[1], limit) if limit >= 0 else None


@dataclass(frozen=True, slots=True)
class Not:
    arg: Formula


@dataclass(frozen=True, slots=True)
class Connective:
    op: str  # and or -> <->
    left: Formula
    right: Formula


@dataclass(frozen=True, slots=True)
class Temporal:
    op: str  # always eventually next historically once previous
    interval: Interval
    arg: Formula


@dataclass(frozen=True, slots=True)
class Until:
    op: str  # until since
    interval: Interval
    left: Formula
    right: Formula


@dataclass(frozen=True, slots=True)
class Quant:
    op: str  # forall exists
    var: str
    sort: str
    body: Formula
    span: Span = field(compare=False)


Formula = (
    BoolConst | Atom | Observed | Fresh | Compare | Not | Connective | Temporal | Until | Quant
)

_PREFIX = {"□": "always", "◇": "eventually"}
_WORD = {
    "U": "until",
    "¬": "not",
    "∧": "and",
    "∨": "or",
    "→": "->",
    "↔": "<->",
    "∀": "forall",
    "∃": "exists",
    "=": "==",
}


class _ToAst(Transformer[Token, Any]):
    @staticmethod
    def _span(token: Token) -> Span:
        return Span(FILE, token.line or 1, token.column or 1)

    def name(self, children: list[Token]) -> Token:
        return children[0]

    def feature(self, children: list[Token]) -> Ref:
        name, *args = children
        return Ref(
            FeatureRef(
                str(name), tuple(Arg(str(a), None, self._span(a)) for a in args), self._span(name)
            )
        )

    def number(self, children: list[Token]) -> Num:
        text = str(children[0])
        if len(text) > MAX_NUMBER:
            raise ParseError(
                f"number of {len(text)} characters (at most {MAX_NUMBER})", self._span(children[0])
            )
        return Num(int(text) if text.isdigit() else float(text))

    def boolean(self, children: list[Token]) -> BoolConst:
        return BoolConst(str(children[0]) == "true")

    def neg(self, children: list[Any]) -> Expr:
        return Unary("-", _expr(children[-1]))

    def abs_(self, children: list[Any]) -> Expr:
        return Unary("abs", _expr(children[1]))

    def func1(self, children: list[Any]) -> Expr:
        return Unary(str(children[0]), _expr(children[1]))

    def func2(self, children: list[Any]) -> Expr:
        return Func(str(children[0]), _expr(children[1]), _expr(children[2]))

    def sampled(self, children: list[Any]) -> Expr:
        return Sampled(str(children[0]), children[1])

    def observed(self, children: list[Any]) -> Observed:
        return Observed(children[1].feature)

    def fresh(self, children: list[Any]) -> Fresh:
        return Fresh(children[1], self.bound([children[2]]) or Fraction(0))

    def string(self, children: list[Token]) -> Str:
        text = str(children[0])
        if len(text) > MAX_NUMBER:
            raise ParseError(
                f"string of {len(text)} characters (at most {MAX_NUMBER})", self._span(children[0])
            )
        return Str(re.sub(r"\\(.)", r"\1", text[1:-1]))

    def expr(self, children: list[Any]) -> Arith:
        return Arith(str(children[1]), _expr(children[0]), _expr(children[2]))

    term = expr

    def comparison(self, children: list[Any]) -> Compare:
        op = str(children[1])
        return Compare(_WORD.get(op, op), _expr(children[0]), _expr(children[2]))

    def not_(self, children: list[Any]) -> Not:
        return Not(_formula(children[1]))

    def temporal(self, children: list[Any]) -> Temporal:
        op = str(children[0])
        interval = children[1] if len(children) == 3 else ANY
        return Temporal(_PREFIX.get(op, op), interval, _formula(children[-1]))

    def until(self, children: list[Any]) -> Until:
        left, op, *rest = children
        interval = rest[0] if len(rest) == 2 else ANY
        return Until(_WORD.get(str(op), str(op)), interval, _formula(left), _formula(rest[-1]))

    def _connective(self, children: list[Any]) -> Connective:
        op = str(children[1])
        return Connective(_WORD.get(op, op), _formula(children[0]), _formula(children[2]))

    iff = imp = or_ = and_ = _connective

    def interval(self, children: list[Any]) -> Interval:
        bracket, lo, hi = children
        if lo is None:
            raise ParseError("an interval cannot start at infinity", self._span(bracket))
        if hi is not None and hi < lo:
            raise ParseError(f"empty interval: {lo} > {hi}", self._span(bracket))
        return Interval(lo, hi)

    def bound(self, children: list[Token]) -> Fraction | None:
        token = children[0]
        if token.type == "INFINITY":
            return None
        text = str(token)
        if len(text) > MAX_NUMBER:
            raise ParseError(
                f"time bound of {len(text)} characters (at most {MAX_NUMBER})", self._span(token)
            )
        unit = text.lstrip("0123456789.")
        return Fraction(text[: len(text) - len(unit)]) * UNITS[unit or "s"]

    def binding(self, children: list[Any]) -> tuple[str, str, Span]:
        return str(children[0]), str(children[1]), self._span(children[1])

    def quant(self, children: list[Any]) -> Formula:
        op = _WORD.get(str(children[0]), str(children[0]))
        return _nest(op, children[1:-1], _formula(children[-1]))

    def forall(self, children: list[Any]) -> Formula:
        return _nest("forall", children[:-1], _formula(children[-1]))


# Built at import, its tables from the cache when the grammar is unchanged (a few ms, not the
# 40 ms of an LALR analysis), so the first formula costs what later ones do.  The transformer runs
# inside the LALR parser: the AST is built without a parse tree.
_PARSER = lalr("mtl.lark", _ToAst())


def _nest(op: str, bindings: list[tuple[str, str, Span]], body: Formula) -> Formula:
    for var, sort, span in reversed(bindings):
        body = Quant(op, var, sort, body, span)
    return body


def _expr(node: Any) -> Expr:
    if isinstance(node, Num | Str | Ref | Arith | Unary | Func | Sampled):
        return node
    if isinstance(node, BoolConst):
        return Num(int(node.value))
    raise ParseError("a formula cannot be used as a number here", _where(node))


def _formula(node: Any) -> Formula:
    if isinstance(node, Ref):
        return Atom(node.feature)
    if isinstance(node, Num | Str | Arith | Unary | Func | Sampled):
        raise ParseError("a number is not a formula: compare it with something", _where(node))
    return node  # type: ignore[no-any-return]


def _where(node: Any) -> Span:
    for f in _feature_refs(node):
        return f.span
    return Span(FILE, 1, 1)


def read_formulas(path: Path) -> list[str]:
    """A formulas file: one formula a line; blank lines and `#` comments skipped."""
    lines = (line.strip() for line in read_text(path).splitlines())
    return [line for line in lines if line and not line.startswith("#")]


def parse_formula(text: str) -> Formula:
    try:
        return _balanced(_formula(_PARSER.parse(text)), 0)  # type: ignore[no-any-return]
    except UnexpectedInput as exc:
        raise _misapplied(exc, text) or _syntax_error(exc, text) from None


MAX_DEPTH = 100  # nesting levels of a formula as written (and/or chains count once)
MAX_EXPANSION = 100_000  # ground features, or atoms of a formula, once quantifiers expand
ASSOCIATIVE = ("and", "or")


def chain(op: str, parts: Sequence[Formula]) -> Formula:
    """`parts` joined by the associative `op` as a balanced tree: a conjunction of a thousand
    parts nests ten levels deep, not a thousand (walkers recurse, Python's parser nests)."""
    if len(parts) == 1:
        return parts[0]
    mid = len(parts) // 2
    return Connective(op, chain(op, parts[:mid]), chain(op, parts[mid:]))


def _links(node: Connective) -> list[Formula]:
    """The operands of a maximal chain of `node.op`, left to right, found without recursion."""
    out: list[Formula] = []
    todo: list[Formula] = [node]
    while todo:
        n = todo.pop()
        if isinstance(n, Connective) and n.op == node.op:
            todo += [n.right, n.left]
        else:
            out.append(n)
    return out


def _balanced(node: Any, depth: int) -> Any:
    """`node` with and/or chains balanced, refused past MAX_DEPTH levels of other nesting."""
    if depth > MAX_DEPTH:
        raise ParseError(f"formula nested more than {MAX_DEPTH} levels deep", _where(node))
    if isinstance(node, Connective) and node.op in ASSOCIATIVE:
        return chain(node.op, [_balanced(n, depth + 1) for n in _links(node)])
    if isinstance(node, Compare | Connective | Arith | Func | Until):
        return replace(
            node, left=_balanced(node.left, depth + 1), right=_balanced(node.right, depth + 1)
        )
    if isinstance(node, Not | Temporal | Unary):
        return replace(node, arg=_balanced(node.arg, depth + 1))
    if isinstance(node, Quant):
        return replace(node, body=_balanced(node.body, depth + 1))
    return node


# What a call takes, as mtl.lark spells them, in the order an unknown name's error lists them.
CALLS = {
    "functions": {"abs": 1, "min": 2, "max": 2, "sqrt": 1, "hypot": 2},
    "terms": {"prev": 1, "delta": 1, "rate": 1, "age": 1},
    "atoms": {"observed": 1, "fresh": 2},
}
_ARITY = {name: n for group in CALLS.values() for name, n in group.items()}
_KNOWN = "; ".join(f"{group}: {', '.join(names)}" for group, names in CALLS.items())
_DURATION = re.compile(r"[0-9]+(\.[0-9]+)?(ms|s|min|h)?")


def _misapplied(exc: UnexpectedInput, text: str) -> ParseError | None:
    """A call the parse failed at that names no function (failing at its `(`), or failed inside
    and is given other arguments than it takes: said at its name, in place of the grammar's
    expected tokens (the innermost such call; one with the arguments it takes says nothing)."""
    at = getattr(getattr(exc, "token", None), "start_pos", None)
    if at is None:
        return None
    try:
        tokens = list(_PARSER.lex(text))
    except UnexpectedInput:
        return None
    for i in range(len(tokens) - 2, -1, -1):  # the innermost call first
        name, paren = tokens[i], tokens[i + 1]
        if paren.type != "LPAR" or (name.type != "NAME" and str(name) not in _ARITY):
            continue  # `always (`, `not (`: no call
        span = Span(FILE, name.line or 1, name.column or 1)
        if name.type == "NAME":
            if paren.start_pos == at:
                return ParseError(f"unknown function {name} ({_KNOWN})", span)
            continue
        args, end = _arguments(tokens, i + 2, text)
        if not (paren.start_pos or 0) < at <= end:
            continue
        if name == "fresh" and not (len(args) == 2 and _DURATION.fullmatch(args[1])):
            return ParseError("fresh(X, d) needs a duration", span)
        wanted = _ARITY[str(name)]
        if len(args) != wanted:
            plural = "s" if wanted > 1 else ""
            return ParseError(f"{name} takes {wanted} argument{plural}, got {len(args)}", span)
        return None
    return None


def _arguments(tokens: list[Token], start: int, text: str) -> tuple[list[str], int]:
    """The arguments of a call whose `(` precedes tokens[start], as written, and the offset of
    its `)` (the end of the text, if none closes it)."""
    depth, begin, args = 0, None, []
    for tok in tokens[start:]:
        pos = tok.start_pos or 0
        begin = pos if begin is None else begin
        if tok.type in ("LPAR", "LSQB"):
            depth += 1
        elif tok.type in ("RPAR", "RSQB") and depth:
            depth -= 1
        elif tok.type in ("COMMA", "RPAR") and not depth:
            if pos > begin or tok.type == "COMMA":
                args.append(text[begin:pos].strip())
            if tok.type == "RPAR":
                return args, pos
            begin = None
    return args, len(text)


def _syntax_error(exc: UnexpectedInput, text: str) -> ParseError:
    span = Span(FILE, getattr(exc, "line", 1) or 1, getattr(exc, "column", 1) or 1)
    if isinstance(exc, UnexpectedEOF) or getattr(getattr(exc, "token", None), "type", "") == "$END":
        lines = text.splitlines() or [""]
        return ParseError(
            "syntax error: the formula ends too early",
            Span(FILE, len(lines), len(lines[-1].rstrip()) + 2),
        )
    if isinstance(exc, UnexpectedCharacters):
        return ParseError(f"syntax error: unexpected character {exc.char!r}", span)
    token = getattr(exc, "token", "")
    expected = sorted(getattr(exc, "expected", ()) or ())
    names = [_EXPECTED[e.lstrip("_")] for e in expected if e.lstrip("_") in _EXPECTED]
    hint = f", expected {', '.join(dict.fromkeys(names))}" if names else ""
    return ParseError(f"syntax error at {str(token)!r}{hint}", span)


_EXPECTED = {
    "NAME": "a feature name",
    "NUMBER": "a number",
    "RPAR": "')'",
    "RSQB": "']'",
    "LPAR": "'('",
    "CMP": "a comparison",
    "ADD": "'+'",
    "MINUS": "'-'",
    "AND": "'and'",
    "OR": "'or'",
    "DURATION": "a time bound",
    "IN": "'in'",
    "BVAR": "a variable",
    "$END": "the end",
}


# ---- what the matcher needs: the features, with variables typed by their quantifier -------


def features(formula: Formula) -> list[FeatureRef]:
    """Every feature occurrence, in order, arguments marked as constants or sorted variables."""
    return list(_walk(formula, {}))


def _walk(node: Any, env: dict[str, str]) -> Iterator[FeatureRef]:
    if isinstance(node, Quant):
        yield from _walk(node.body, {**env, node.var: node.sort})
    elif isinstance(node, Atom | Ref | Observed):
        f = node.feature
        yield FeatureRef(
            f.name, tuple(Arg(a.name, env.get(a.name), a.span) for a in f.args), f.span
        )
    else:
        for child in children(node):
            yield from _walk(child, env)


def children(node: Any) -> tuple[Any, ...]:
    """The subformulas and subexpressions of a node, left to right (a term over samples, or
    `fresh`, has its feature as its child)."""
    if isinstance(node, Compare | Connective | Arith | Func | Until):
        return node.left, node.right
    if isinstance(node, Not | Temporal | Unary | Sampled | Fresh):
        return (node.arg,)
    if isinstance(node, Quant):
        return (node.body,)
    return ()


def _feature_refs(node: Any) -> Iterator[FeatureRef]:
    todo = [node]  # without recursion: it also locates errors in formulas nested too deeply
    while todo:
        n = todo.pop()
        if isinstance(n, Atom | Ref | Observed):
            yield n.feature
        todo += reversed(children(n))


def self_comparisons(formula: Formula) -> list[str]:
    """One warning line per comparison of a term with itself (`X != X`: its value never
    changes), naming where it is and suggesting `prev(X)`; under `previous`, saying that the
    operator took the whole comparison (`previous (X) != X` reads as `previous (X != X)`)."""
    out: list[str] = []
    todo: list[tuple[Any, bool]] = [(formula, False)]
    while todo:
        n, past = todo.pop()
        if isinstance(n, Compare) and n.left == n.right:
            said = "always true" if n.op in ("==", "<=", ">=") else "always false"
            line = f"{_where(n)}: {unparse(n)} compares a term with itself ({said})"
            for ref in list(_feature_refs(n.left))[:1]:
                line += f"; its value at the previous sample is prev({feature_text(ref)})"
            if past:
                line += (
                    " (previous applies to the whole comparison: "
                    "`previous (X) != X` reads as `previous (X != X)`)"
                )
            out.append(line)
        is_previous = isinstance(n, Temporal) and n.op == "previous"
        todo += [(c, past or is_previous) for c in reversed(children(n))]
    return out


def formula_warnings(formula: Formula) -> list[str]:
    """What a formula says that its author likely did not mean: comparisons of a term with
    itself, and ages that make no deadline."""
    return self_comparisons(formula) + undated_ages(formula)


def undated_ages(formula: Formula) -> list[str]:
    """One warning line per `age(X)` the monitor cannot make a deadline of (inside arithmetic,
    a function, or compared with another term): it is read only at the states other samples
    make, so a sample that stops is not caught when it grows too old."""
    out: list[str] = []
    timed: set[int] = set()  # the ages compared with a number: deadlines
    todo: list[Any] = [formula]
    while todo:
        n = todo.pop()
        if isinstance(n, Compare) and (bound := age_bound(n)) is not None:
            timed.add(id(bound[0]))
        if isinstance(n, Sampled) and n.op == "age" and id(n) not in timed:
            x = feature_text(n.arg.feature)
            out.append(
                f"{n.arg.feature.span}: age({x}) here makes no deadline (it is read only at "
                f"states other samples make): compare age({x}) with a number, "
                f"age({x}) <= 2, or write fresh({x}, 2s), and a state is made where it crosses"
            )
        todo += reversed(children(n))
    return out


def quantifiers(formula: Formula) -> Iterator[Quant]:
    if isinstance(formula, Quant):
        yield formula
    for child in children(formula):
        yield from quantifiers(child)


def deadlines(formula: Formula) -> bool:
    """Whether the formula waits on a bounded window of the future (`eventually[0, 5]`,
    `always[0, 5]`, `next[0, 5]`, `until[0, 5]`): time passing alone may decide it."""
    todo: list[Any] = [formula]
    while todo:
        n = todo.pop()
        future = (isinstance(n, Temporal) and n.op in ("eventually", "always", "next")) or (
            isinstance(n, Until) and n.op == "until"
        )
        if future and n.interval.hi is not None:
            return True
        todo += children(n)
    return False


# ---- formulas as text: each with the parentheses it needs, so a witness quotes it exactly ----

# how tightly each construct binds, loosest first, as mtl.lark nests them
QUANT, IFF, IMP, OR, AND, UNTIL, UNARY, CMP, ADD, MUL, FACTOR = range(11)
_LEVEL = {"<->": IFF, "->": IMP, "or": OR, "and": AND}


def unparse(node: Formula | Expr, unit: Fraction | int = 1) -> str:
    """A formula or expression as text that parses back to the same tree (a parsed formula's
    and each of its subformulas'), with only the parentheses it needs (and around a comparison
    under `not`, for the reader).  Interval bounds are times `unit` seconds (a progressor's
    trees count in the stream's units)."""
    return _unparse(node, unit)[0]


def _unparse(n: Any, unit: Fraction | int) -> tuple[str, int]:
    """The text of `n` and how tightly it binds."""

    def wrap(child: Any, level: int) -> str:
        text, own = _unparse(child, unit)
        return f"({text})" if own < level else text

    if isinstance(n, BoolConst):
        return ("true" if n.value else "false"), FACTOR
    if isinstance(n, Atom | Ref):
        return feature_text(n.feature), FACTOR
    if isinstance(n, Observed):
        return f"observed({feature_text(n.feature)})", FACTOR
    if isinstance(n, Num):
        return (repr(n.value) if abs(n.value) != float("inf") else "1e999"), FACTOR
    if isinstance(n, Str):
        return '"' + re.sub(r'(["\\])', r"\\\1", n.value) + '"', FACTOR
    if isinstance(n, Sampled):
        return f"{n.op}({feature_text(n.arg.feature)})", FACTOR
    if isinstance(n, Fresh):
        return f"fresh({feature_text(n.arg.feature)}, {decimal(n.limit)}s)", FACTOR
    if isinstance(n, Func):
        return f"{n.op}({_unparse(n.left, unit)[0]}, {_unparse(n.right, unit)[0]})", FACTOR
    if isinstance(n, Unary):
        if n.op != "-":
            return f"{n.op}({_unparse(n.arg, unit)[0]})", FACTOR
        inner = isinstance(n.arg, Unary) and n.arg.op == "-"
        return "-" + (f"({wrap(n.arg, FACTOR)})" if inner else wrap(n.arg, FACTOR)), FACTOR
    if isinstance(n, Arith):
        level = ADD if n.op in "+-" else MUL
        return f"{wrap(n.left, level)} {n.op} {wrap(n.right, level + 1)}", level
    if isinstance(n, Compare):
        return f"{wrap(n.left, ADD)} {n.op} {wrap(n.right, ADD)}", CMP
    if isinstance(n, Not):
        return "not " + wrap(n.arg, UNARY if not isinstance(n.arg, Compare) else FACTOR), UNARY
    if isinstance(n, Temporal):
        return f"{n.op}{interval_text(n.interval, unit)} {wrap(n.arg, UNARY)}", UNARY
    if isinstance(n, Until):
        interval = interval_text(n.interval, unit)
        return f"{wrap(n.left, UNARY)} {n.op}{interval} {wrap(n.right, UNTIL)}", UNTIL
    if isinstance(n, Connective):
        level = _LEVEL[n.op]
        if n.op in ASSOCIATIVE:  # a chain as written (the parser balances it again)
            return f" {n.op} ".join(wrap(link, level + 1) for link in _links(n)), level
        left, right = (level, level + 1) if n.op == "<->" else (level + 1, level)
        return f"{wrap(n.left, left)} {n.op} {wrap(n.right, right)}", level
    if isinstance(n, Quant):
        return f"{n.op} {n.var} in {n.sort}: {_unparse(n.body, unit)[0]}", QUANT
    raise TypeError(type(n).__name__)


def feature_text(f: FeatureRef) -> str:
    """`Name[a, b]` (a feature without arguments: `Name`)."""
    return f.name + (f"[{', '.join(a.name for a in f.args)}]" if f.args else "")


def interval_text(i: Interval, unit: Fraction | int = 1) -> str:
    """An interval as written, in seconds (`unit`: seconds per time unit of its bounds);
    nothing for [0, oo]."""
    if i == ANY:
        return ""
    hi = "oo" if i.hi is None else decimal(i.hi * unit)
    return f"[{decimal(i.lo * unit)}, {hi}]"


# ---- feature keys written as text (state files, --feature): read once per spelling ------

_KEY = re.compile(r"\s*([^\s\[\],]+)\s*(?:\[([^\[\]]*)\])?\s*")


@lru_cache(maxsize=1 << 14)
def feature_key(text: str) -> FeatureKey | None:
    """The key a state file writes as text (`Close[uav1, uav2]`), read once per spelling."""
    found = _KEY.fullmatch(text)
    if found is None:
        return None
    args = tuple(a.strip() for a in found.group(2).split(",")) if found.group(2) else ()
    return FeatureKey(found.group(1), args) if all(args) else None


# lark compiles its lexers' expressions on first use (~9 ms): one formula using every kind of
# token pays that here too.
_PARSER.parse(
    "forall x in S: always[0, 1ms] (A[x] > -1.5 * abs(B[x]) + max(rate(A[x]), 1) and not C[x] or "
    'eventually D[x] == "s" -> E[x] until[0, 2] F[x] <-> true)'
)
