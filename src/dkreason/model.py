"""Frozen data passed between the stages: parse → check → expand → match → request.

Names inside specs and formulas stay as written (`uav1`, `hr:Heading`, `<http://…#UAV>`) so a
spec file can be written back unchanged; the check stage resolves them to IRIs per platform.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Any, Literal, NamedTuple

from .errors import Span

ArgKind = Literal["object", "some", "every"]
IdValue = int | str


# ---- topic specifications (SSL_T, thesis listing 4.2) -------------------------------------


@dataclass(frozen=True, slots=True)
class TopicArg:
    """One argument of a topic feature, or the entity of a sort/object topic.

    `id_field` is the message field holding the object's id; None means an implicit object
    (the topic carries that object only, no filter needed).
    """

    kind: ArgKind
    name: str
    id_field: str | None
    span: Span = dataclasses.field(default=Span("<api>"), compare=False)


@dataclass(frozen=True, slots=True)
class TopicFeature:
    """A feature a topic's field carries; with `observations`, `name` is a sensor instead and
    the field carries what it observes (`observations of thermo1 = msg.temperature`), which
    the platform's adapters tell (sosa:observes): a feature of one object, no arguments here."""

    name: str
    field: str
    args: tuple[TopicArg, ...]
    span: Span = dataclasses.field(default=Span("<api>"), compare=False)
    observations: bool = False


@dataclass(frozen=True, slots=True)
class TopicSpec:
    """A topic and what it carries: features, or the objects of a sort, or one object.

    `rate` (Hz) and `delay` (seconds: the most a sample's valid time may lag its arrival) are
    the stream's declared quality, None where the spec leaves them out (thesis 8.2)."""

    name: str
    msgtype: str
    features: tuple[TopicFeature, ...] = ()
    entity: TopicArg | None = None
    span: Span = dataclasses.field(default=Span("<api>"), compare=False)
    rate: Fraction | None = None
    delay: Fraction | None = None

    @property
    def kind(self) -> Literal["features", "sort", "object"]:
        if self.features:
            return "features"
        assert self.entity is not None
        return "object" if self.entity.kind == "object" else "sort"


# ---- ontologies and mappings ----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Signature:
    """A feature's arity and, per argument, the sorts allowed (a unionOf gives several)."""

    iri: str
    arg_sorts: tuple[tuple[str, ...], ...]

    @property
    def arity(self) -> int:
        return len(self.arg_sorts)


@dataclass(frozen=True, slots=True)
class Adapted:
    """Where a feature an adapter made came from: the adapter rule that derived it
    (file:line) and the told triples it rests on, (subject, predicate, object) as IRIs."""

    rule: Span
    axioms: tuple[tuple[str, str, str], ...]


@dataclass(frozen=True, slots=True)
class Ontology:
    """One platform's told axioms, read without inference (signatures must stay as asserted);
    with `reasoning = "owl-rl"`, `types` and `same_as` also hold what OWL 2 RL entails, each
    such pair in `entailed` with the axiom it follows from."""

    platform: str
    file: str
    classes: frozenset[str]
    features: Mapping[str, Signature]
    subclass_of: tuple[tuple[str, str], ...]
    equivalent: tuple[tuple[str, str], ...]
    individuals: frozenset[str]
    types: tuple[tuple[str, str], ...]
    same_as: tuple[tuple[str, str], ...]
    ids: Mapping[str, IdValue]
    prefixes: Mapping[str, str]
    entailed: Mapping[tuple[str, str], str] = field(default_factory=dict)
    # every property assertion about an object, as told: (object, property, literal value)
    # and (object, property, other object); rule files read them (data_property/4,
    # object_property/4)
    data_values: tuple[tuple[str, str, IdValue], ...] = ()
    object_values: tuple[tuple[str, str, str], ...] = ()
    # the features adapters made (rules/adapters/), by IRI; any other is the class pattern's
    adapted: Mapping[str, Adapted] = field(default_factory=dict)
    # what adapters found to be no feature, and why (a formula naming one is told)
    unadapted: Mapping[str, str] = field(default_factory=dict)
    # (sensor, feature, object): what each sensor observes, as its adapters say (SSL_T
    # `observations of SENSOR`)
    observations: tuple[tuple[str, str, str], ...] = ()

    @property
    def sorts(self) -> frozenset[str]:
        return self.classes - self.features.keys()

    @property
    def properties(self) -> frozenset[str]:
        """The properties its assertions use."""
        return frozenset(p for _, p, _ in (*self.data_values, *self.object_values))


@dataclass(frozen=True, slots=True)
class FeatureInfo:
    """A feature as `dkreason info --config C` lists it: its signature (local names, a union's
    sorts joined by ∪) and where it came from (the class pattern, or an adapter rule)."""

    platform: str
    name: str
    iri: str
    signature: tuple[str, ...]
    origin: str

    def __str__(self) -> str:
        return f"{self.name}({', '.join(self.signature)})"

    def to_json(self) -> dict[str, Any]:
        return {
            "platform": self.platform,
            "feature": self.name,
            "iri": self.iri,
            "signature": list(self.signature),
            "origin": self.origin,
        }


BridgeType = Literal["equiv", "into", "onto", "incompat", "compat", "same"]
BRIDGE_TYPES: tuple[BridgeType, ...] = ("equiv", "into", "onto", "incompat", "compat", "same")


@dataclass(frozen=True, slots=True)
class BridgeRule:
    """A COWL bridge rule between an entity of the source and one of the target platform."""

    type: BridgeType
    source: str
    target: str
    span: Span = dataclasses.field(compare=False)


@dataclass(frozen=True, slots=True)
class Mapping_:
    source: str
    target: str
    file: str
    rules: tuple[BridgeRule, ...]


# ---- formulas: the features they need -------------------------------------------------------


class FeatureKey(NamedTuple):
    """A ground feature as the state stream names it (`Close[uav1, uav2]`): made from typed
    parts, never parsed from text.  A named tuple, so states (dicts keyed by it) hash it in C
    from its strings' cached hashes."""

    name: str
    args: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"{self.name}[{', '.join(self.args)}]" if self.args else self.name


@dataclass(frozen=True, slots=True)
class Arg:
    """A feature argument in a formula: a constant object, or a variable bound to a sort."""

    name: str
    sort: str | None = None  # the quantifier's sort for a variable, None for a constant
    span: Span = dataclasses.field(default=Span("<formula>"), compare=False)

    @property
    def is_variable(self) -> bool:
        return self.sort is not None


@dataclass(frozen=True, slots=True)
class FeatureRef:
    """A feature as written in a formula, before expansion (`Altitude[x]` with x in UAV)."""

    name: str
    args: tuple[Arg, ...]
    span: Span = dataclasses.field(default=Span("<formula>"), compare=False)


@dataclass(frozen=True, slots=True)
class GroundFeature:
    """A feature over objects of the local platform: the unit a stream request is made of.

    `name` and `args` are local names as the formula (or the expansion) writes them; `iri` and
    `arg_iris` are what they resolve to.
    """

    name: str
    args: tuple[str, ...]
    iri: str
    arg_iris: tuple[str, ...]
    span: Span = dataclasses.field(default=Span("<formula>"), compare=False)
    key: FeatureKey = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "key", FeatureKey(self.name, self.args))


# ---- the stream request (thesis 5.6: state stream → features → topics → arguments) ---------


def ros_name(topic: str, namespace: str | None) -> str:
    """A spec topic's ROS graph name, as ROS resolves it: an absolute name stands for itself, a
    relative one lies under the platform's namespace (`/` without one)."""
    return topic if topic.startswith("/") else (namespace or "/").rstrip("/") + "/" + topic


def stream_name(platform: str, topic: str) -> str:
    """A platform's topic as a person reads it: `bot/odom` for a relative name, `bot:/odom` for
    an absolute one (not `bot//odom`).  The one place that joins them."""
    return f"{platform}:{topic}" if topic.startswith("/") else f"{platform}/{topic}"


@dataclass(frozen=True, slots=True)
class TopicMatch:
    """A topic to merge for a feature: where to read the value, which messages to keep."""

    platform: str
    topic: str
    msgtype: str
    field: str
    filter: tuple[tuple[str, IdValue], ...]
    as_feature: str
    as_args: tuple[str, ...]
    # the topic's declared quality (TopicSpec's), if any: the topic's, so not part of its key
    rate: Fraction | None = dataclasses.field(default=None, compare=False)
    delay: Fraction | None = dataclasses.field(default=None, compare=False)

    def to_json(self, local: str, namespace: str | None = None) -> dict[str, object]:
        """`namespace`: the platform's, which gives the topic its ROS name (`ros_name`)."""
        out: dict[str, object] = {"platform": self.platform, "topic": self.topic}
        if namespace is not None:
            out["ros_name"] = ros_name(self.topic, namespace)
        out |= {"msgtype": self.msgtype, "field": self.field, "filter": dict(self.filter)}
        if self.platform != local:
            out["as"] = {"feature": self.as_feature, "args": list(self.as_args)}
        if self.rate is not None:
            out["rate"] = float(self.rate)  # Hz
        if self.delay is not None:
            out["delay"] = float(self.delay)  # s
        return out


@dataclass(frozen=True, slots=True)
class FeatureRequest:
    """A ground feature, the topics it is read from and, with --best-source, the relevant
    topics ranked after the chosen one when it declares a rate (`standby`): read but feeding
    nothing, so a monitor sees them run and can re-match to them when the chosen one's
    samples stop and it is set aside."""

    feature: GroundFeature
    topics: tuple[TopicMatch, ...]
    standby: tuple[TopicMatch, ...] = ()


@dataclass(frozen=True, slots=True)
class StreamRequest:
    """What the Stream Processor must subscribe to for one formula."""

    formula: str
    local: str
    features: tuple[FeatureRequest, ...]
    warnings: tuple[str, ...] = ()
    namespaces: tuple[tuple[str, str], ...] = ()  # platform → ROS namespace, where set
    # spec topic names (without a leading slash) that several platforms' specs use: such a
    # name is never read bare (`T`, `/T`) for a remote platform (stream/binding.py)
    shared_names: frozenset[str] = frozenset()
    best_source: bool = False  # each feature read from its first topic, not their merge

    def without(self, aside: frozenset[tuple[str, str]]) -> StreamRequest:
        """The request with the (platform, topic)s a monitor set aside dropped, as the shipped
        policy drops them (`degraded`): a feature whose chosen topic (--best-source) is aside
        is read from the first topic standing by that is not.  For a monitor that cannot
        match again, having no knowledge base (a batch worker)."""
        if not aside:
            return self

        def kept(topics: tuple[TopicMatch, ...]) -> tuple[TopicMatch, ...]:
            return tuple(t for t in topics if (t.platform, t.topic) not in aside)

        features = []
        for f in self.features:
            topics, standby = kept(f.topics), kept(f.standby)
            if not topics and standby:
                topics, standby = standby[:1], standby[1:]
            features.append(FeatureRequest(f.feature, topics, standby))
        return replace(self, features=tuple(features))

    def to_json(self) -> dict[str, Any]:
        namespaces = dict(self.namespaces)

        def shown(topics: tuple[TopicMatch, ...]) -> list[dict[str, Any]]:
            return [t.to_json(self.local, namespaces.get(t.platform)) for t in topics]

        features = []
        for f in self.features:
            feature: dict[str, Any] = {"feature": f.feature.name, "args": list(f.feature.args)}
            feature["topics"] = shown(f.topics)
            if f.standby:  # --best-source: the topics ranked after the chosen one
                feature["standby"] = shown(f.standby)
            features.append(feature)
        out: dict[str, Any] = {"formula": self.formula, "features": features}
        if self.warnings:
            out["warnings"] = list(self.warnings)
        return out
