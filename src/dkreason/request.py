"""Matches → the stream request of thesis 5.6: per feature, the topics to merge, each with the
field to read and the id filter that selects the feature's objects in the topic's messages."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterator, Sequence
from dataclasses import replace
from fractions import Fraction

from .inputs.numbers import decimal
from .kb import KnowledgeBase
from .match import Aside, Match, Rejected, match
from .model import (
    FeatureKey,
    FeatureRequest,
    GroundFeature,
    IdValue,
    StreamRequest,
    TopicMatch,
)
from .names import local_name
from .parse.formula import Formula, Temporal, Until, children
from .parse.formula import features as refs
from .plan import Plan


def request(
    kb: KnowledgeBase,
    plan: Plan,
    *,
    max_delay: Fraction | None = None,
    best_source: bool = False,
    degraded: Aside = frozenset(),
) -> StreamRequest:
    """The topics of every ground feature of the plan, matched in one query (`max_delay`:
    the monitor's, which the policy may veto topics by; `best_source`: each feature's first
    topic only; `degraded`: the sources a monitor set aside, which the policy vetoes)."""
    ground = list(plan.ground)
    matches, rejected = match(kb, ground, max_delay, degraded)
    made = build_request(
        kb, plan.text, ground, matches, rejected, plan.warnings, best_source=best_source
    )
    coarse = too_fine(plan, made.features)
    return replace(made, warnings=(*made.warnings, *coarse)) if coarse else made


def too_fine(plan: Plan, features: tuple[FeatureRequest, ...]) -> list[str]:
    """A bounded window finer than the declared period of every topic feeding a feature it
    reads (`eventually[0, 50ms]` over a 1 Hz topic): no sample need fall inside it.  One line
    per formula, window and feature, said before any message is read."""
    feeding = {f.feature.key: f.topics for f in features}
    out: dict[str, None] = {}
    for formula in plan.formulas:
        for instance in formula.instances:
            for node in _windows(instance.tree):
                assert node.interval.hi is not None
                width = node.interval.hi - node.interval.lo
                for ref in refs(node):
                    key = FeatureKey(ref.name, tuple(a.name for a in ref.args))
                    rates = [(t, t.rate) for t in feeding.get(key, ())]
                    if rates and all(r is not None and width < 1 / r for _, r in rates):
                        slowest = ", ".join(f"{t.topic} at {decimal(r)} Hz" for t, r in rates if r)
                        window = (
                            f"{node.op}[{decimal(node.interval.lo)}, {decimal(node.interval.hi)}]"
                        )
                        out[
                            f"{formula.text}: {window} is finer than the period of every topic "
                            f"of {key} ({slowest}): a sample need not fall inside it"
                        ] = None
    return list(out)


def _windows(node: Formula) -> Iterator[Temporal | Until]:
    """The bounded temporal operators of a formula."""
    if isinstance(node, Temporal | Until) and node.interval.hi is not None:
        yield node
    for child in children(node):
        yield from _windows(child)


def build_request(
    kb: KnowledgeBase,
    formula: str,
    ground: list[GroundFeature],
    matches: list[Match],
    rejected: list[Rejected],
    notes: Sequence[str] = (),
    *,
    best_source: bool = False,
) -> StreamRequest:
    """`notes`: warnings about the formula itself (plan.FormulaPlan.warnings), said first;
    `best_source`: of each feature's topics in the policy's order, the first only, not their
    merge (the thesis merges them all); the others stand by when the first one declares a
    rate, read by a monitor so that it can re-route to them when the first one's samples stop
    (a topic declaring none is never set aside: nothing to read them for)."""
    per_feature: dict[int, dict[TopicMatch, int]] = defaultdict(dict)  # ordered, no repeats
    for m in matches:
        topic = topic_match(kb, m)
        if topic is not None:
            per_feature[m.query][topic] = min(m.rank, per_feature[m.query].get(topic, m.rank))
    features = []
    for q, g in enumerate(ground):
        ranked = tuple(
            sorted(
                per_feature[q],
                key=lambda t: (
                    per_feature[q][t],  # the policy's rank (0 unless it ranks), then
                    t.platform != kb.local,
                    t.platform,
                    kb.platforms[t.platform].rank[t.topic],
                    t.filter,
                ),
            )
        )
        if not best_source:
            features.append(FeatureRequest(g, ranked))
        else:  # the others stand by if the first one can be set aside: it declares a rate
            features.append(
                FeatureRequest(g, ranked[:1], ranked[1:] if ranked[:1] and ranked[0].rate else ())
            )
    warnings = [*notes, *kb.warnings, *_warnings(kb, ground, rejected)]
    namespaces = tuple(
        (p.name, p.namespace)
        for p in (kb.config.platforms if kb.config else ())
        if p.namespace is not None
    )
    return StreamRequest(
        formula,
        kb.local,
        tuple(features),
        tuple(dict.fromkeys(warnings)),
        namespaces,
        kb.shared_names(),
        best_source,
    )


def topic_match(kb: KnowledgeBase, m: Match) -> TopicMatch | None:
    spec = kb.platforms[m.platform].resolved[m.topic]
    feature = spec.features[m.feature_index - 1]
    filter_: dict[str, IdValue] = {}
    for arg, value in zip(feature.args, m.ids, strict=True):
        if arg.id_field and filter_.setdefault(arg.id_field, value) != value:
            return None  # one field would need two values: this topic cannot carry the tuple
    return TopicMatch(
        m.platform,
        m.topic,
        spec.msgtype,
        feature.field,
        tuple(filter_.items()),
        local_name(feature.iri),
        tuple(local_name(o) for o in m.objects),
        spec.rate,
        spec.delay,
    )


def _warnings(
    kb: KnowledgeBase, ground: list[GroundFeature], rejected: list[Rejected]
) -> list[str]:
    """Remote candidates the remote ontology rejects: a mapping error to tell the user about."""
    out = []
    for r in rejected:
        platform = kb.platforms[r.platform]
        fits = {
            i
            for i, o in enumerate(r.objects, 1)
            if kb.engine.query("fits", r.platform, r.feature, i, o)
        }
        why = "; ".join(
            kb.misfit(platform, r.feature, i, o)
            for i, o in enumerate(r.objects, 1)
            if i not in fits
        )
        mapped = f"{local_name(r.feature)}[{', '.join(local_name(o) for o in r.objects)}]"
        out.append(
            f"{ground[r.query].key}: maps to {mapped} on {r.platform}, which "
            f"{r.platform}'s ontology rejects: {why}"
        )
    return out
