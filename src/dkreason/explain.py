"""Why a topic was matched, and why another was not — computed on demand.

A proof replays the clauses of the rule files (`Datalog.rules`, with their file:line) against
the engine: the engine says which bindings hold, the clauses say why, so a rule an extension
file adds appears in explanations like any shipped rule.  Told facts are the leaves and name
where they came from: the spec statement, the ontology axiom, the bridge rule, the formula.

Why-not looks at each candidate of `rules/matching.dl` (`candidate/7`: the feature read as a
feature of one platform, its arguments as that platform's objects) and reports the first
condition of `sound_candidate/6` or `matched_topic/7` that fails for it, descending through
the rules to the told facts that are missing.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from .datalog import Comparison, Literal, Row, Rule, Term, Value, Var
from .facts import THING, told_types
from .kb import KnowledgeBase
from .match import Match
from .model import GroundFeature
from .names import local_name

Env = dict[str, Value]
Pattern = tuple[Value | None, ...]  # (predicate, *args); None = any value
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
        if self.fact[0] == predicate:
            yield self
        for child in self.children:
            yield from child.find(predicate)


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


@dataclass(frozen=True, slots=True)
class TopicWhy:
    platform: str
    topic: str
    filter: tuple[tuple[str, Value], ...]
    summary: tuple[str, ...]
    proof: Proof


@dataclass(frozen=True, slots=True)
class TopicWhyNot:
    platform: str
    topic: str | None
    reason: str
    trace: Failure


@dataclass(frozen=True, slots=True)
class FeatureExplanation:
    feature: str
    why: tuple[TopicWhy, ...]
    why_not: tuple[TopicWhyNot, ...]


@dataclass(frozen=True, slots=True)
class Explanation:
    formula: str
    features: tuple[FeatureExplanation, ...]


# ---- reading facts: told facts with their sources, derived facts generically ---------------

_BRIDGE = {"equiv": "≡", "same": "=", "into": "⊑", "onto": "⊒", "incompat": "⊥", "compat": "★"}
# Told facts in words, by the column names rules/schema.dl declares.
_GLOSSES = {
    "equivalent_class": "{Class} ≡ {Other} ({Platform} axiom)",
    "subclass_of": "{Sub} ⊑ {Super} ({Platform} axiom)",
    "class_type": "{Class} : {Sort} ({Platform} axiom)",
    "same_as": "{Object} = {Other} ({Platform} sameAs)",
    "feature": "{Feature} is a feature of {Platform} with {Arity} argument(s)",
    "feature_arg": "{Feature} argument {Position} takes {Sort} ({Platform})",
    "individual": "{Object} is an object of {Platform}",
    "sort": "{Sort} is a sort of {Platform}",
    "bridge": "{SourceEntity} {Type} {TargetEntity} (bridge {SourcePlatform}→{TargetPlatform})",
    "topic_feature": "{Topic} carries {Feature} in {Field} ({Platform})",
    "topic_filter": "{Topic} feature {K} filters on {Field1}, {Field2}, {Field3} ({Platform})",
    "id_property": "{Object} has id {Id} ({Platform})",
    "name_digits": "{Object} ends in the digits {Digits} ({Platform})",
    "same_rep": "{Object} is in the sameAs class of {Class} ({Platform})",
    "sort_rep": "{Sort} is in the class of sorts equivalent to {Class} ({Platform})",
}


class Reader:
    """Renders facts with local names and says where told facts come from."""

    def __init__(self, kb: KnowledgeBase, ground: list[GroundFeature]) -> None:
        self.kb, self.ground = kb, ground
        self.bridges = {
            (m.source, r.source, m.target, r.target, r.type): r.span
            for m in kb.mappings
            for r in m.rules
        }
        self.derived = {r.head.predicate for r in kb.engine.rules}
        self.told: dict[str, set[tuple[str, str]]] = {}  # platform → its objects' told types

    def name(self, value: Value | None) -> str:
        if value is None:
            return "_"
        if value == "":
            return "–"
        return local_name(value) if isinstance(value, str) and "/" in value else str(value)

    def columns(self, fact: Pattern | Row) -> dict[str, Any]:
        """The fact's values by the column names its relation is declared with."""
        relation = self.kb.engine.schema.get(str(fact[0]))
        if relation is None or relation.arity != len(fact) - 1:
            return {}
        return relation.row(fact[1:])  # type: ignore[arg-type]

    def text(self, fact: Pattern) -> str:
        pred, *args = fact
        c = self.columns(fact)
        named = {k: self.name(v) for k, v in c.items()}
        query = c.get("Query")
        if pred == "wanted" and isinstance(query, int) and query < len(self.ground):
            return f"the formula needs {self.ground[query].key}"
        if pred == "topic_arg" and None not in args:
            if c["Entity"] == "":
                return "{Topic} has no argument {Position}".format(**named)
            return "{Topic} argument {Position}: {Kind} {Entity}".format(**named) + (
                f" = {named['IdField']}" if c["IdField"] else " (implicit)"
            )
        if pred == "class_type" and None not in args:  # the told member, if not the class
            told = self.typed_member(str(c["Platform"]), str(c["Class"]), str(c["Sort"]))
            if told != c["Class"]:
                return "{} : {Sort} ({Platform} axiom), in the sameAs class of {Class}".format(
                    self.name(told), **named
                )
        if pred in _GLOSSES and None not in args:
            if pred == "bridge":
                named["Type"] = _BRIDGE.get(str(c["Type"]), str(c["Type"]))
            return _GLOSSES[str(pred)].format(**named)
        return f"{pred}({', '.join(self.name(x) for x in args)})"

    def told_path(self, fact: Row) -> list[tuple[str, str, str, str]]:
        """same_rep(P, X, R) or sort_rep(P, X, R) as the told sameAs, subClassOf or
        equivalentClass links from X to its class's representative R (breadth first)."""
        pred, platform, start, goal = (str(x) for x in fact)
        ont = self.kb.platforms[platform].ontology
        if pred == "same_rep":
            told = [(a, b, "=") for a, b in ont.same_as]
        else:
            told = [(a, b, "⊑") for a, b in ont.subclass_of] + [
                (a, b, "≡") for a, b in ont.equivalent
            ]
        near: dict[str, list[tuple[str, str, str]]] = defaultdict(list)
        for a, b, sym in told:
            near[a].append((a, b, sym))
            near[b].append((a, b, sym))
        came: dict[str, tuple[str, str, str] | None] = {start: None}
        todo = [start]
        while todo and goal not in came:
            x = todo.pop(0)
            for edge in near[x]:
                y = edge[1] if edge[0] == x else edge[0]
                if y not in came:
                    came[y] = edge
                    todo.append(y)
        path, x = [], goal
        while came.get(x) is not None:
            a, b, sym = came[x]  # type: ignore[misc]
            path.append((a, b, sym, f"{platform} axiom, {ont.file}"))
            x = a if b == x else b
        return path[::-1]

    def typed_member(self, platform: str, rep: str, sort: str) -> str:
        """The member of sameAs class `rep` told (or, untyped, taken) to be a `sort`."""
        members = [str(o) for _, o, _ in self.kb.engine.query("same_rep", platform, None, rep)]
        if platform not in self.told:  # once an explanation, not once a fact shown
            self.told[platform] = set(told_types(self.kb.platforms[platform].ontology))
        return next((o for o in sorted(members) if (o, sort) in self.told[platform]), rep)

    def source(self, fact: Row) -> str:
        """Where a told fact comes from: file:line, or the ontology axiom and its file."""
        pred, *args = fact
        kb, c = self.kb, self.columns(fact)
        if pred == "bridge":
            span = self.bridges.get(tuple(args))  # type: ignore[arg-type]
            return str(span) if span else "bridge rule"
        if pred in ("topic", "topic_feature", "topic_arg", "topic_filter"):
            spec = kb.platforms[str(c["Platform"])].specs.get(str(c["Topic"]))
            if spec is None:
                return "topic specification"
            if pred in ("topic_feature", "topic_filter") or (
                pred == "topic_arg" and c["Entity"] == ""
            ):
                return str(spec.features[int(c["K"]) - 1].span)
            if pred == "topic_arg":
                return str(spec.features[int(c["K"]) - 1].args[int(c["Position"]) - 1].span)
            return str(spec.span)
        if pred == "wanted":
            q = int(c["Query"])
            return str(self.ground[q].span) if q < len(self.ground) else "<formula>"
        if pred == "online" and kb.live:
            return "live: the platform is present (liveliness)"
        if pred in ("local", "mapping", "platform", "online"):
            return str(kb.config.path) if kb.config else "configuration"
        if pred in ("position", "sort_kind"):
            return "built in (src/dkreason/facts.py)"
        owner = kb.platforms.get(str(c.get("Platform"))) if c else None
        if owner is None:
            return "knowledge base"
        file = owner.ontology.file
        if pred == "class_type":  # told of the class's member that has that type
            pred, args = "type_of", [args[0], self.typed_member(*(str(a) for a in args)), args[2]]
            c = {"Object": args[1], "Sort": args[2]}
        subject = f"<{args[1]}>" if len(args) > 1 else ""
        if (
            pred == "subclass_of"
            and c["Super"] == THING
            and (str(c["Sub"]), THING) not in set(owner.ontology.subclass_of)
        ):
            return f"implicit: every sort is a subclass of owl:Thing ({file})"
        entailed = (
            owner.ontology.entailed.get((str(args[1]), str(args[2])))
            if pred in ("type_of", "same_as") and len(args) == 3
            else None
        )
        if entailed:
            return f"{entailed} ({file})"
        if (
            pred == "type_of"
            and c["Sort"] == THING
            and (str(c["Object"]), THING) not in set(owner.ontology.types)
        ):
            return f"implicit: every object is a Thing ({file})"
        kind = {
            "equivalent_class": "owl:equivalentClass",
            "subclass_of": "rdfs:subClassOf",
            "type_of": "rdf:type",
            "same_as": "owl:sameAs",
            "individual": "NamedIndividual",
            "sort": "owl:Class",
            "feature": "subClassOf (…Relation ⊓ …)",
            "feature_arg": f"subClassOf ∀arg{c.get('Position', '')}",
            "id_property": "id data property",
            "name_digits": "digits ending the name",
            "same_rep": "owl:sameAs closure",
            "sort_rep": "subClassOf/equivalentClass closure",
        }
        return f"{subject} {kind.get(str(pred), str(pred))}, {file}"


# ---- replaying clauses ------------------------------------------------------------------------


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
        which vary per process): the same proof and the same failure every run."""
        if pattern not in self._answers:
            pred, *args = pattern
            self._answers[pattern] = sorted(
                ((str(pred), *row) for row in self.kb.engine.query(str(pred), *args)),
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

    def _solve_one(self, item: Literal | Comparison, env: Env) -> Iterator[Env]:
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
        for row in self.rows(pattern):
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
    def refute(self, goal: Pattern, depth: int = 12) -> Failure:
        best: tuple[int, Rule, Env] | None = None
        for rule in self.clauses.get(str(goal[0]), []):
            env = _unify(rule.head.args, goal[1:], {}, partial=True)
            if env is None:
                continue
            reached, at = self._furthest(rule.body, env)
            if best is None or reached > best[0]:
                best = (reached, rule, at)
        text = self.reader.text(goal)
        if best is None:  # a told fact, or no clause can produce it
            return Failure(goal, text, None, None, f"no {text}", nearby=self._nearby(goal))
        reached, rule, env = best
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

    def _furthest(self, body: tuple[Literal | Comparison, ...], env: Env) -> tuple[int, Env]:
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
            for extended in reversed(list(itertools.islice(self._solve_one(body[i], current), 50))):
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


# ---- explanations for a formula -----------------------------------------------------------


def explain(
    kb: KnowledgeBase,
    formula: str,
    ground: list[GroundFeature],
    matches: list[Match],
    feature: str | None = None,
    topic: str | None = None,
) -> Explanation:
    from .errors import DkError
    from .match import wanted_rows
    from .parse.formula import feature_key

    selected = list(range(len(ground)))
    if feature is not None:
        wanted_key = feature_key(feature)
        selected = [q for q, g in enumerate(ground) if g.key == wanted_key]
        if not selected:
            raise DkError(
                f"{feature} is not a feature of the formula (its features: "
                f"{', '.join(str(g.key) for g in ground)})"
            )
    if topic is not None and not any(topic in p.specs for p in kb.platforms.values()):
        raise DkError(f"no topic {topic!r} on any platform")
    reader = Reader(kb, ground)
    replay = Replayer(kb, reader)
    with kb.engine.given({"wanted": wanted_rows(ground)}):
        features = []
        for q in selected:
            mine = [m for m in matches if m.query == q and topic in (None, m.topic)]
            why = tuple(_why(kb, replay, m) for m in mine)
            why_not: tuple[TopicWhyNot, ...] = ()
            if not mine:
                platforms = (
                    [p for p, plat in kb.platforms.items() if topic in plat.specs]
                    if topic
                    else [str(r[2]) for r in replay.rows(("context", kb.local, None))]
                )
                why_not = tuple(w for p in platforms for w in _why_not(kb, replay, q, p, topic))
            features.append(FeatureExplanation(str(ground[q].key), why, why_not))
    return Explanation(formula, tuple(features))


def _why(kb: KnowledgeBase, replay: Replayer, m: Match) -> TopicWhy:
    from .match import padded
    from .request import topic_match

    fact: Row = (
        "relevant_topic",
        m.query,
        m.platform,
        m.topic,
        m.feature_index,
        *padded(m.objects),
        *m.ids,
        *("",) * (3 - len(m.ids)),
    )
    proof = replay.prove(fact)
    assert proof is not None, f"the engine derived {fact} but no clause replays it"
    entry = topic_match(kb, m)
    return TopicWhy(
        m.platform, m.topic, entry.filter if entry else (), _summary(replay.reader, proof), proof
    )


def _why_not(
    kb: KnowledgeBase, replay: Replayer, q: int, platform: str, topic: str | None
) -> list[TopicWhyNot]:
    key = replay.reader.ground[q].key
    candidates = replay.rows(("candidate", q, platform, None, None, None, None, None))
    if not candidates:
        failure = replay.refute(("candidate", q, platform, None, None, None, None, None))
        return [
            TopicWhyNot(
                platform,
                topic,
                f"{key} has no candidate on {platform}: {_reason(kb, replay, failure)}",
                failure,
            )
        ]
    out = []
    for _, _, _, _, g, *objects in candidates:
        arity = len(replay.reader.ground[q].args)
        shown = ", ".join(replay.reader.name(o) for o in objects[:arity])
        mapped = f"{replay.reader.name(g)}[{shown}]"
        sound: Row = ("sound_candidate", q, platform, g, *objects)
        if not replay.holds(sound):
            failure = replay.refute(sound)
            reason = f"{mapped} rejected: {_reason(kb, replay, failure)}"
        else:
            failure = replay.refute(("matched_topic", q, platform, topic, None, *objects))
            reason = f"{_reason(kb, replay, failure)}; {key} maps to {mapped}" + (
                f" on {platform}" if platform != kb.local else ""
            )
        out.append(TopicWhyNot(platform, topic, reason, failure))
    return out


def _reason(kb: KnowledgeBase, replay: Replayer, failure: Failure) -> str:
    """The first failed condition, in the words of the matcher's own relations."""
    cond = failure.condition
    name = replay.reader.name
    if cond is None:
        return failure.condition_text + (
            f" (there is: {failure.nearby[0]})" if failure.nearby else ""
        )
    pred, *a = cond
    if failure.negated:
        if pred == "excluded":
            return f"an incompat bridge rule excludes {name(a[2])} here"
        return f"{failure.condition_text} holds"
    if pred == "fits" and a[3]:
        platform = kb.platforms[str(a[0])]
        return kb.misfit(platform, str(a[1]), int(a[2]), str(a[3]))  # type: ignore[arg-type]
    if pred == "object_candidate":
        return f"{name(a[1])} has no counterpart on {a[0]} (no sameAs or 'same' bridge reaches it)"
    if pred == "feature_candidate":
        return f"{name(a[1])} has no counterpart on {a[0]} (no equivalence reaches it)"
    if pred == "topic_feature" and a[1] is not None:
        carried = [name(r[4]) for r in replay.rows(("topic_feature", a[0], a[1], None, None, None))]
        return f"{a[1]} carries {', '.join(carried) or 'nothing'}, not {name(a[3])}"
    if pred == "accepts" and None not in a[:4]:
        args = replay.rows(("topic_arg", a[0], a[1], a[2], a[3], None, None, None))
        said = ", ".join(f"{r[5]} {name(r[6])}" if r[5] != "object" else name(r[6]) for r in args)
        source = replay.reader.source(args[0]) if args else ""
        return f"argument {a[3]} is {said} ({source}), not {name(a[4])}"
    if isinstance(failure.because, Failure):
        return _reason(kb, replay, failure.because)
    nearby = f" (there is: {failure.nearby[0]})" if failure.nearby else ""
    return f"no {failure.condition_text}{nearby}"


def _summary(reader: Reader, proof: Proof) -> tuple[str, ...]:
    """The proof's chains in one line each: feature, then each argument, then the topic."""
    lines = []
    for node in itertools.islice(proof.find("feature_candidate"), 1):
        _, _, start, end = node.fact
        chain = _chain(
            reader, node, str(start), str(end), ("equivalent_class", "bridge", "subclass_of")
        )
        lines.append(f"feature: {chain}")
    seen = set()
    for node in proof.find("arg_candidate"):
        _, _, start, end = node.fact
        if start == "" or (start, end) in seen:
            continue
        seen.add((start, end))
        lines.append(f"object: {_chain(reader, node, str(start), str(end), ('same_as', 'bridge'))}")
    for node in (*proof.find("accepts"), *proof.find("carries")):
        if node.fact[0] == "accepts":  # accepts(R, T, K, I, C)
            _, _, topic, _, position, obj = node.fact
        else:  # carries(R, G, I, C, T, K): a sort argument found through C's sorts
            _, _, _, position, obj, topic, _ = node.fact
        sort_args = [
            leaf
            for leaf in node.leaves()
            if leaf.fact[0] == "topic_arg" and leaf.fact[5] in ("some", "every")
        ]
        for told in (leaf for leaf in node.leaves() if leaf.fact[0] == "class_type"):
            if sort_args:
                chain = _chain(
                    reader,
                    node,
                    str(told.fact[3]),
                    str(sort_args[0].fact[6]),
                    ("subclass_of", "equivalent_class"),
                )
                entailed = (
                    f" [{told.source}]"
                    if told.source and told.source.startswith("entailed")
                    else ""
                )
                lines.append(
                    f"argument {position} of {topic}: {reader.name(obj)} : {chain}{entailed}"
                )
    carried = (
        f"topic: {leaf.text} [{leaf.source}]"
        for leaf in proof.leaves()
        if leaf.fact[0] == "topic_feature"
    )
    return tuple(lines) + tuple(dict.fromkeys(carried))


def _chain(reader: Reader, node: Proof, start: str, end: str, kinds: tuple[str, ...]) -> str:
    """`A ≡ B (where) ≡ C (where)`: the told links of a proof, in order from start to end."""
    edges = []
    for leaf in node.leaves():
        pred, *a = leaf.fact
        if (
            pred in ("same_rep", "sort_rep")
            and ("same_as" if pred == "same_rep" else "subclass_of") in kinds
        ):
            edges += reader.told_path(leaf.fact)  # a class's representative: the told links
        if pred not in kinds:
            continue
        if pred == "bridge":
            left, right, sym = str(a[1]), str(a[3]), _BRIDGE.get(str(a[4]), "?")
            where = f"bridge {a[0]}→{a[2]}, {leaf.source}"
        else:
            left, right = str(a[1]), str(a[2])
            sym = {"equivalent_class": "≡", "same_as": "=", "subclass_of": "⊑"}[str(pred)]
            where = f"{a[0]} axiom, {leaf.source.split(', ')[-1] if leaf.source else ''}"
        edges.append((left, right, sym, where))
    text, current = reader.name(start), start
    while edges:
        step = next((e for e in edges if current in (e[0], e[1])), None)
        if step is None:
            break
        edges.remove(step)
        current = step[1] if step[0] == current else step[0]
        text += f" {step[2]} {reader.name(current)} ({step[3]})"
    if current == start and start == end and not edges:
        text += " (as the formula writes it)" if "bridge" in kinds else ""
    return text


# ---- rendering -----------------------------------------------------------------------------


def _rule_ref(rule: Rule | None) -> str:
    return str(rule.span) if rule else ""


def proof_json(p: Proof) -> dict[str, object]:
    out: dict[str, object] = {"fact": p.text, "atom": list(p.fact)}
    if p.rule:
        out["rule"] = _rule_ref(p.rule)
        out["rule_text"] = p.rule.text
    if p.source:
        out["source"] = p.source
    if p.children:
        out["children"] = [proof_json(c) for c in p.children]
    return out


def failure_json(f: Failure) -> dict[str, object]:
    out: dict[str, object] = {"goal": f.text, "failed": f.condition_text, "negated": f.negated}
    if f.rule:
        out["rule"] = _rule_ref(f.rule)
    if f.nearby:
        out["nearby"] = list(f.nearby)
    if isinstance(f.because, Failure):
        out["because"] = failure_json(f.because)
    elif isinstance(f.because, Proof):
        out["because"] = proof_json(f.because)
    return out


def to_json(e: Explanation) -> dict[str, object]:
    return {
        "formula": e.formula,
        "features": [
            {
                "feature": f.feature,
                "why": [
                    {
                        "platform": w.platform,
                        "topic": w.topic,
                        "filter": dict(w.filter),
                        "summary": list(w.summary),
                        "proof": proof_json(w.proof),
                    }
                    for w in f.why
                ],
                "why_not": [
                    {
                        "platform": n.platform,
                        "topic": n.topic,
                        "reason": n.reason,
                        "trace": failure_json(n.trace),
                    }
                    for n in f.why_not
                ],
            }
            for f in e.features
        ],
    }


def to_text(e: Explanation) -> str:
    lines: list[str] = []
    for f in e.features:
        lines.append(f.feature)
        for w in f.why:
            ids = ", ".join(f"{k} = {v}" for k, v in w.filter)
            lines.append(f"  ✔ {w.topic} on {w.platform}" + (f" ({ids})" if ids else ""))
            lines += [f"      {s}" for s in w.summary]
            lines.append("      proof:")
            _proof_lines(w.proof, 8, lines)
        for n in f.why_not:
            lines.append(f"  ✘ {n.topic or 'no topic'} on {n.platform}: {n.reason}")
            lines.append("      trace:")
            _failure_lines(n.trace, 8, lines)
        if not f.why and not f.why_not:
            lines.append("  (no topic, and no platform to look on)")
    return "\n".join(lines)


def _proof_lines(p: Proof, indent: int, out: list[str]) -> None:
    where = f"  [{_rule_ref(p.rule)}]" if p.rule else f"  ← {p.source}" if p.source else ""
    out.append(" " * indent + p.text + where)
    for c in p.children:
        _proof_lines(c, indent + 2, out)


def _failure_lines(f: Failure, indent: int, out: list[str]) -> None:
    pad = " " * indent
    rule = f"  [{_rule_ref(f.rule)}]" if f.rule else ""
    verb = "holds" if f.negated else "fails"
    out.append(
        f"{pad}{f.text}: {'' if f.negated else 'no '}{f.condition_text}"
        f"{' (which excludes it)' if f.negated else ''}{rule}".replace(
            f": no no {f.condition_text}", f": no {f.condition_text}"
        )
    )
    out += [f"{pad}  there is: {n}" for n in f.nearby]
    if isinstance(f.because, Failure):
        _failure_lines(f.because, indent + 2, out)
    elif isinstance(f.because, Proof):
        out.append(f"{pad}  it {verb} because:")
        _proof_lines(f.because, indent + 4, out)


def to_dot(e: Explanation) -> str:
    """Graphviz: one cluster per feature, proofs as trees, failures as red chains."""
    lines = ["digraph explanation {", "  rankdir=LR;", "  node [shape=box, fontsize=10];"]
    counter = itertools.count()

    def quote(text: str) -> str:  # real newlines in `text` become DOT line breaks
        escaped = text.replace("\\", "\\\\").replace('"', '\\"')
        return '"' + escaped.replace("\n", "\\n") + '"'

    def proof(p: Proof) -> str:
        node = f"n{next(counter)}"
        label = p.text + (f"\n{_rule_ref(p.rule)}" if p.rule else f"\n{p.source or ''}")
        style = "" if p.rule else ", style=filled, fillcolor=lightgrey"
        lines.append(f"  {node} [label={quote(label)}{style}];")
        for c in p.children:
            lines.append(f"  {node} -> {proof(c)};")
        return node

    def failure(f: Failure) -> str:
        node = f"n{next(counter)}"
        label = f"{f.text}\nfails at: {f.condition_text}\n{_rule_ref(f.rule)}"
        lines.append(f"  {node} [label={quote(label)}, color=red];")
        if isinstance(f.because, Failure):
            lines.append(f"  {node} -> {failure(f.because)} [color=red];")
        elif isinstance(f.because, Proof):
            lines.append(f"  {node} -> {proof(f.because)};")
        return node

    for i, f in enumerate(e.features):
        lines.append(f"  subgraph cluster_{i} {{ label={quote(f.feature)};")
        for w in f.why:
            root = proof(w.proof)
            lines.append(f"  w{i}_{root} [label={quote('✔ ' + w.topic)}, shape=ellipse];")
            lines.append(f"  w{i}_{root} -> {root};")
        for n in f.why_not:
            root = failure(n.trace)
            lines.append(
                f"  x{i}_{root} [label={quote('✘ ' + n.reason)}, shape=ellipse, color=red];"
            )
            lines.append(f"  x{i}_{root} -> {root};")
        lines.append("  }")
    lines.append("}")
    return "\n".join(lines)
