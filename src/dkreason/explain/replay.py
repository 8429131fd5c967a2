"""Proof replay: a derived fact re-derived from the clauses of the loaded rule files
(`Datalog.rules`, with their file:line) against the engine, which says which bindings hold; and
for a goal that does not hold, the clause that came closest and the condition it failed on."""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from ..kb import KnowledgeBase
from ..policy.syntax import Comparison, Literal, Row, Rule, Term, Value, Var
from .provenance import Pattern, Reader

Env = dict[str, Value]
MAX_DEPTH = 40


@dataclass(frozen=True, slots=True)
class Proof:
    """A derived fact with the clause that derived it, or a told fact with its source."""

    fact: Row
    text: str
    rule: Rule | None = None
    source: str | None = None
    children: tuple[Proof, ...] = ()

    def leaves(self) -> Iterator[Proof]:
        if not self.children:
            yield self
        for child in self.children:
            yield from child.leaves()

    def find(self, predicate: str) -> Iterator[Proof]:
        return (p for p in self.steps() if p.fact[0] == predicate)

    def steps(self) -> Iterator[Proof]:
        """Every step of the proof, itself first, depth first."""
        yield self
        for child in self.children:
            yield from child.steps()


@dataclass(frozen=True, slots=True)
class Failure:
    """A goal that does not hold: the clause that came closest and the condition it failed on."""

    goal: Pattern
    text: str
    rule: Rule | None
    condition: Pattern | None  # the failed body condition, instantiated as far as known
    condition_text: str
    negated: bool = False
    nearby: tuple[str, ...] = ()  # told facts close to a missing one
    because: Failure | Proof | None = None


class Replayer:
    def __init__(self, kb: KnowledgeBase, reader: Reader) -> None:
        self.kb, self.reader = kb, reader
        self.clauses: dict[str, list[Rule]] = defaultdict(list)
        for rule in kb.engine.rules:
            self.clauses[rule.head.predicate].append(rule)
        self._answers: dict[Pattern, list[Row]] = {}
        self._proofs: dict[tuple[Row, int], Proof | None] = {}

    # engine access, cached for one explanation
    def rows(self, pattern: Pattern) -> list[Row]:
        """The rows matching `pattern`, in a fixed order (the engine's follows string hashes,
        which vary per process): the same proof and the same failure every run.  A pattern
        the policy's rules cannot be asked with (a variable they need bound is free) has
        none: an explanation never asks the engine what it cannot answer."""
        if pattern not in self._answers:
            pred, *args = pattern
            engine = self.kb.engine
            askable = str(pred) in engine.schema and not engine.askable(str(pred), args)
            self._answers[pattern] = sorted(
                ((str(pred), *row) for row in (engine.query(str(pred), *args) if askable else ())),
                key=lambda row: [(type(v).__name__, v) for v in row],
            )
        return self._answers[pattern]

    def holds(self, fact: Row) -> bool:
        return bool(self.rows(fact))

    def solutions(self, body: tuple[Literal | Comparison, ...], env: Env) -> Iterator[Env]:
        if not body:
            yield env
            return
        first, rest = body[0], body[1:]
        for extended in self._solve_one(first, env):
            yield from self.solutions(rest, extended)

    def _solve_one(
        self, item: Literal | Comparison, env: Env, assume: Row | None = None
    ) -> Iterator[Env]:
        """The bindings under which `item` holds; an atom of `assume`'s relation holds for
        `assume` alone (how a step is refuted for one candidate)."""
        if isinstance(item, Comparison):
            left, right = _value(item.left, env), _value(item.right, env)
            if left is not None and right is not None and _compare(item.op, left, right):
                yield env
            return
        pattern = _instantiate(item, env)
        if item.negated:
            if None not in pattern and not self.holds(pattern):  # type: ignore[arg-type]
                yield env
            return
        if assume is not None and assume[0] == item.predicate:
            rows = [assume] if _unify(item.args, assume[1:], env) is not None else []
        else:
            rows = self.rows(pattern)
        for row in rows:
            extended = _unify(item.args, row[1:], env)
            if extended is not None:
                yield extended

    # proofs: shortest first (iterative deepening), never through a fact already on the path
    def prove(self, fact: Row) -> Proof | None:
        for depth in range(1, MAX_DEPTH + 1):
            proof = self._prove(fact, depth, frozenset())
            if proof is not None:
                return proof
        return None

    def _prove(self, fact: Row, depth: int, path: frozenset[Row]) -> Proof | None:
        pred = str(fact[0])
        if pred not in self.clauses:
            return (
                Proof(fact, self.reader.text(fact), source=self.reader.source(fact))
                if self.holds(fact)
                else None
            )
        key = (fact, depth)
        if key in self._proofs:
            return self._proofs[key]
        result = None
        if depth > 0:
            result = self._by_clauses(fact, depth, path | {fact})
        self._proofs[key] = result
        return result

    def _by_clauses(self, fact: Row, depth: int, path: frozenset[Row]) -> Proof | None:
        for rule in self.clauses[str(fact[0])]:
            env = _unify(rule.head.args, fact[1:], {})
            if env is None:
                continue
            for solution in self.solutions(rule.body, env):
                children = self._children(rule, solution, depth, path)
                if children is not None:
                    return Proof(fact, self.reader.text(fact), rule=rule, children=children)
        return None

    def _children(
        self, rule: Rule, env: Env, depth: int, path: frozenset[Row]
    ) -> tuple[Proof, ...] | None:
        out = []
        for item in rule.body:
            if isinstance(item, Comparison):
                text = f"{_value(item.left, env)} {item.op} {_value(item.right, env)}"
                out.append(Proof(("compare", text), text, source="arithmetic"))
                continue
            fact: Row = _instantiate(item, env)  # type: ignore[assignment]
            if item.negated:
                text = f"no {self.reader.text(fact)}"
                out.append(Proof(("not", *fact), text, source="negation: no such fact"))
                continue
            if fact in path:
                return None
            child = self._prove(fact, depth - 1, path)
            if child is None:
                return None
            out.append(child)
        return tuple(out)

    # failures: the clause whose body gets furthest, and the condition it stops at
    def refute(self, goal: Pattern, depth: int = 12, assume: Row | None = None) -> Failure:
        """Why `goal` does not hold (with `assume`, for that one row of the relation its
        clauses read: one candidate, say)."""
        best: tuple[int, Rule, Env] | None = None
        for rule in self.clauses.get(str(goal[0]), []):
            env = _unify(rule.head.args, goal[1:], {}, partial=True)
            if env is None:
                continue
            reached, at = self._furthest(rule.body, env, assume)
            if best is None or reached > best[0]:
                best = (reached, rule, at)
        text = self.reader.text(goal)
        if best is None:  # a told fact, or no clause can produce it
            return Failure(goal, text, None, None, f"no {text}", nearby=self._nearby(goal))
        reached, rule, env = best
        if reached == len(rule.body):  # it holds, for values the goal leaves open
            return Failure(goal, text, rule, None, f"nothing fails: {text} holds")
        item = rule.body[reached]
        if isinstance(item, Comparison):
            cond = f"{_value(item.left, env)} {item.op} {_value(item.right, env)}"
            return Failure(goal, text, rule, None, f"not {cond}")
        condition = _instantiate(item, env)
        if item.negated:
            proof = self.prove(condition) if None not in condition else None  # type: ignore[arg-type]
            return Failure(
                goal,
                text,
                rule,
                condition,
                self.reader.text(condition),
                negated=True,
                because=proof,
            )
        because = (
            self.refute(condition, depth - 1)
            if depth > 0 and str(condition[0]) in self.clauses
            else None
        )
        nearby = self._nearby(condition) if str(condition[0]) not in self.clauses else ()
        return Failure(
            goal, text, rule, condition, self.reader.text(condition), nearby=nearby, because=because
        )

    def _furthest(
        self, body: tuple[Literal | Comparison, ...], env: Env, assume: Row | None
    ) -> tuple[int, Env]:
        best = (0, env)
        stack = [(0, env)]
        seen = 0
        while stack and seen < 5000:
            i, current = stack.pop()
            seen += 1
            if i > best[0]:
                best = (i, current)
            if i == len(body):
                return best
            found = itertools.islice(self._solve_one(body[i], current, assume), 50)
            for extended in reversed(list(found)):
                stack.append((i + 1, extended))
        return best

    def _nearby(self, pattern: Pattern) -> tuple[str, ...]:
        """Told facts that share the missing fact's leading arguments (what is there instead)."""
        pred, *args = pattern
        if str(pred) in self.clauses:
            return ()
        for i in reversed(range(len(args))):  # the same fact with one argument set free
            if args[i] is None:
                continue
            rows = self.rows((pred, *args[:i], None, *args[i + 1 :]))
            if rows:
                return tuple(f"{self.reader.text(r)} [{self.reader.source(r)}]" for r in rows[:5])
        return ()


def _value(term: Term, env: Env) -> Value | None:
    return env.get(term.name) if isinstance(term, Var) else term


def _instantiate(item: Literal, env: Env) -> Pattern:
    return (item.predicate, *(_value(t, env) for t in item.args))


def _unify(
    terms: tuple[Term, ...], values: tuple[Value | None, ...], env: Env, partial: bool = False
) -> Env | None:
    out = dict(env)
    for term, value in zip(terms, values, strict=True):
        if value is None:
            if partial:
                continue
            return None
        if isinstance(term, Var):
            if term.name in out and out[term.name] != value:
                return None
            out[term.name] = value
        elif term != value:
            return None
    return out


def _compare(op: str, left: Value, right: Value) -> bool:
    a: Any = left
    try:
        return bool(
            {
                "<": a < right,
                "<=": a <= right,
                ">": a > right,
                ">=": a >= right,
                "==": a == right,
                "!=": a != right,
            }[op]
        )
    except TypeError:
        return False
