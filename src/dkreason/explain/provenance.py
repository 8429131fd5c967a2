"""Facts in words, and where told facts come from: the spec statement (file:line:col), the
ontology axiom (subject, axiom kind, file), the bridge rule (file:line), the formula."""

from __future__ import annotations

from collections import defaultdict
from fractions import Fraction
from typing import Any

from ..adapt import origin
from ..facts import THING, told_types
from ..inputs.numbers import decimal
from ..kb import KnowledgeBase
from ..model import GroundFeature, TopicSpec
from ..names import local_name
from ..parse.sslt import format_quality
from ..policy.syntax import Row, Rule, Value

Pattern = tuple[Value | None, ...]  # (predicate, *args); None = any value

BRIDGE = {"equiv": "≡", "same": "=", "into": "⊑", "onto": "⊒", "incompat": "⊥", "compat": "★"}
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

# Derived relations of the shipped policy (rules/matching.dl, rules/federation.dl) that
# explanations put in words of their own, with the columns those words read.  A policy may
# have a relation of the same name that means something else: it is worded only where the
# loaded policy declares it with these columns, and shown as it is otherwise.
WORDED = {
    "feature_candidate": ("Platform", "LocalFeature", "Feature"),
    "object_candidate": ("Platform", "LocalClass", "Class"),
    "excluded": ("Platform", "LocalFeature", "Feature"),
    "arg_candidate": ("Platform", "LocalObject", "Object"),
    "accepts": ("Platform", "Topic", "K", "Position", "Object"),
    "carries": ("Platform", "Feature", "Position", "Object", "Topic", "K"),
}


def nanoseconds(ns: int) -> str:
    """A duration the rules hold in whole nanoseconds, as a person writes it."""
    return f"{decimal(Fraction(ns, 10**6))}ms" if ns < 10**9 else f"{decimal(Fraction(ns, 10**9))}s"


def declared(spec: TopicSpec) -> str:
    """A topic's declared quality in words ('' if it declares none)."""
    return ", ".join(f"{name} {value}" for name, value in format_quality(spec))


class Reader:
    """Renders facts with local names and says where told facts come from."""

    def __init__(self, kb: KnowledgeBase, ground: list[GroundFeature]) -> None:
        self.kb, self.ground = kb, ground
        self.bridges = {
            (m.source, r.source, m.target, r.target, r.type): r.span
            for m in kb.mappings
            for r in m.rules
        }
        self.told: dict[str, set[tuple[str, str]]] = {}  # platform → its objects' told types
        # the rule files of one's own, whose rules an explanation names in its summary
        self.own_files = {f.file for f in kb.engine.files if not f.shipped}

    def own(self, rule: Rule | None) -> bool:
        """A rule of a file of one's own, not of dkreason's."""
        return rule is not None and rule.span.file in self.own_files

    def name(self, value: Value | None) -> str:
        if value is None:
            return "_"
        if value == "":
            return "–"
        if isinstance(value, str) and "/" in value and not value.startswith("/"):
            return local_name(value)  # an IRI; a ROS name (`/gps/fix`) stands as written
        return str(value)

    def columns(self, fact: Pattern | Row) -> dict[str, Any]:
        """The fact's values by the column names its relation is declared with; none if it is
        declared otherwise than explanations read it (WORDED)."""
        relation = self.kb.engine.schema.get(str(fact[0]))
        if (
            relation is None
            or relation.arity != len(fact) - 1
            or WORDED.get(relation.name, relation.columns) != relation.columns
        ):
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
        if pred == "topic_property" and None not in args and isinstance(c["Value"], int):
            return "{Topic} declares {Property} {} ({Platform})".format(
                nanoseconds(c["Value"]), **named
            )
        if pred == "max_delay" and None not in args and isinstance(c["Delay"], int):
            return f"the monitor's --max-delay is {nanoseconds(c['Delay'])}"
        if pred in _GLOSSES and None not in args:
            if pred == "bridge":
                named["Type"] = BRIDGE.get(str(c["Type"]), str(c["Type"]))
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
        told = kb.engine.told.get(fact)
        if told is not None:  # a rule file's fact, or a row of its table
            return str(told)
        if pred == "bridge":
            span = self.bridges.get(tuple(args))  # type: ignore[arg-type]
            return str(span) if span else "bridge rule"
        if pred in ("topic", "topic_feature", "topic_arg", "topic_filter", "topic_property"):
            spec = kb.platforms[str(c["Platform"])].specs.get(str(c["Topic"]))
            if spec is None:
                return "topic specification"
            if pred not in ("topic_feature", "topic_filter", "topic_arg"):
                return str(spec.span)
            feature = spec.features[int(c["K"]) - 1]
            position = int(c["Position"]) if pred == "topic_arg" and c["Entity"] != "" else 0
            # `observations of imu1` names no argument: the entry says the object
            return str(
                feature.args[position - 1].span
                if 0 < position <= len(feature.args)
                else feature.span
            )
        if pred == "max_delay":
            return "--max-delay"
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
        if pred in ("feature", "feature_arg") and str(args[1]) in owner.ontology.adapted:
            return origin(owner.ontology, str(args[1]))
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
