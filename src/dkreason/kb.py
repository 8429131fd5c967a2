"""A knowledge base: every platform's ontology, specs and mappings as facts in one engine.

Built once per config; the matching rules then answer each formula with a few batched queries.
Specs are checked against their ontology as they are loaded or added (thesis 5.3), and mapping
rules against both ontologies they join, so a bad file fails at load time with its line.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .datalog import Datalog, Row, gc_paused
from .errors import DkError, NameError_, ParseError, SortError, Span
from .facts import (
    STATIC,
    Facts,
    ResolvedArg,
    ResolvedFeature,
    ResolvedSpec,
    merge,
    ontology_facts,
    rows_of,
    spec_facts,
)
from .model import BridgeRule, IdValue, Mapping_, Ontology, TopicArg, TopicSpec
from .names import Kind, NameIndex, article, local_name
from .parse.config import RULES_HOME, Config, read_config

RULES_DIR = RULES_HOME / "rules"
_TRAILING_DIGITS = re.compile(r"(\d+)$")


@dataclass
class Platform:
    ontology: Ontology
    names: NameIndex
    specs: dict[str, TopicSpec] = field(default_factory=dict)
    resolved: dict[str, ResolvedSpec] = field(default_factory=dict)
    specs_path: Path | None = None

    @property
    def name(self) -> str:
        return self.ontology.platform

    def object_id(self, iri: str) -> IdValue | None:
        """The object's `id` data property, else the digits ending its local name (thesis)."""
        if iri in self.ontology.ids:
            return self.ontology.ids[iri]
        match = _TRAILING_DIGITS.search(local_name(iri))
        return int(match.group(1)) if match else None


class KnowledgeBase:
    def __init__(self, local: str, platforms: dict[str, Platform],
                 mappings: tuple[Mapping_, ...], rule_files: tuple[Path, ...] = (),
                 config: Config | None = None) -> None:
        self.local = local
        self.platforms = platforms
        self.mappings = mappings
        self.config = config
        self.warnings: list[str] = []
        self.engine = Datalog()
        for path in (*sorted(RULES_DIR.glob("*.dl")), *rule_files):
            self.engine.load_file(path)
        facts = merge(STATIC, {"local": [(local,)],
                               "platform": [(p,) for p in platforms],
                               "mapping": [(m.source, m.target) for m in mappings],
                               "bridge": [(m.source, r.source, m.target, r.target, r.type)
                                          for m in mappings for r in self._checked(m)]},
                      *(ontology_facts(p.ontology) for p in platforms.values()),
                      *(spec_facts(p.name, s) for p in platforms.values()
                        for s in p.resolved.values()))
        for pred, rows in rows_of(facts):
            self.engine.assert_rows(pred, rows)
        self.engine.materialize()
        for p in platforms.values():
            self._check_specs(p, list(p.resolved))
        joined = {m.source for m in mappings if m.target == local} | \
                 {m.target for m in mappings if m.source == local}
        for name in platforms:
            if name != local and name not in joined:
                self.warnings.append(f"platform {name} is joined to {local} by no mapping "
                                     f"file: its topics are not used")
        for m in mappings:
            if local not in (m.source, m.target):
                self.warnings.append(f"mapping {m.source}→{m.target} ({m.file}) does not "
                                     f"involve the local platform {local}: unused")

    @classmethod
    def from_config(cls, path: Path) -> KnowledgeBase:
        with gc_paused():
            return cls._load(path)

    @classmethod
    def _load(cls, path: Path) -> KnowledgeBase:
        from .parse.cowl import read_bridge_rules
        from .parse.owl import read_ontology
        from .parse.sslt import read_specs

        config = read_config(path)
        platforms: dict[str, Platform] = {}
        for files in config.platforms:
            ontology = read_ontology(files.ontology, files.name)
            platform = Platform(ontology, _name_index(ontology), specs_path=files.specs)
            if files.specs is not None:
                for spec in read_specs(files.specs).specs:
                    platform.specs[spec.name] = spec
                    platform.resolved[spec.name] = resolve_spec(platform, spec)
            platforms[files.name] = platform
        mappings = tuple(Mapping_(m.source, m.target, str(m.file), read_bridge_rules(m.file))
                         for m in config.mappings)
        return cls(config.local, platforms, mappings, config.rules, config)

    # ---- specs -------------------------------------------------------------------------

    def add_spec(self, platform: str, spec: TopicSpec) -> ResolvedSpec:
        """Check `spec` against the platform's ontology and add it; on error nothing changes."""
        p = self.platform(platform)
        if spec.name in p.specs:
            raise DkError(f"topic {spec.name} already exists on {platform}")
        resolved = resolve_spec(p, spec)
        self._change(spec_facts(platform, resolved), self.engine.assert_rows)
        p.specs[spec.name], p.resolved[spec.name] = spec, resolved
        try:
            self._check_specs(p, [spec.name])
        except DkError:
            self.remove_spec(platform, spec.name)
            raise
        return resolved

    def remove_spec(self, platform: str, name: str) -> TopicSpec:
        p = self.platform(platform)
        if name not in p.specs:
            raise NameError_(f"no topic {name!r} on {platform}", Span("<api>"))
        self._change(spec_facts(platform, p.resolved[name]), self.engine.retract_rows)
        del p.resolved[name]
        return p.specs.pop(name)

    def _change(self, facts: Facts, how: Callable[[str, list[Row]], None]) -> None:
        """Assert or retract spec facts; the views that read topics are computed again."""
        self.engine.thaw(facts.keys())
        for pred, rows in rows_of(facts):
            how(pred, rows)
        self.engine.materialize()

    def platform(self, name: str) -> Platform:
        if name not in self.platforms:
            raise DkError(f"unknown platform {name!r} (known: {', '.join(self.platforms)})")
        return self.platforms[name]

    def _check_specs(self, p: Platform, names: list[str]) -> None:
        """Every argument of the named specs fits its feature's signature (rules/signature.dl)."""
        if not names:
            return
        topic = names[0] if len(names) == 1 else None
        fitting = set(self.engine.query("spec_arg_fits", p.name, topic, None, None))
        for name in names:
            spec, resolved = p.specs[name], p.resolved[name]
            for k, (feature, rfeature) in enumerate(zip(spec.features, resolved.features,
                                                        strict=True), 1):
                for i, (arg, rarg) in enumerate(zip(feature.args, rfeature.args,
                                                    strict=True), 1):
                    if (p.name, name, k, i) not in fitting:
                        raise SortError(f"topic {name}: argument {i} of {feature.name} "
                                        f"does not fit: {self.misfit(p, rfeature.iri, i, rarg)}",
                                        arg.span)

    def misfit(self, p: Platform, feature: str, i: int, arg: ResolvedArg | str) -> str:
        """Why an object or sort does not fit argument i of a feature, in one phrase."""
        allowed = " or ".join(local_name(s) for s in p.ontology.features[feature].arg_sorts[i - 1])
        fname = local_name(feature)
        if isinstance(arg, str) or arg.kind == "object":
            iri = arg if isinstance(arg, str) else arg.iri
            sorts = self.sorts_of(p.name, iri)
            shown = ", ".join(local_name(s) for s in sorts) or "of no sort"
            return (f"{local_name(iri)} is a{'n' if shown[0] in 'AEIOU' else ''} {shown}, "
                    f"{fname} needs {allowed}")
        return f"sort {local_name(arg.iri)} is not subsumed by {allowed}, which {fname} needs"

    def sorts_of(self, platform: str, iri: str) -> list[str]:
        """The most specific told sorts of an object, for messages."""
        ont = self.platform(platform).ontology
        told = sorted({c for o, c in ont.types if o == iri})
        return told or sorted({str(s) for (_, _, s) in self.engine.query("instance_of", platform,
                                                                           iri, None)})

    # ---- mappings ----------------------------------------------------------------------

    def _checked(self, m: Mapping_) -> tuple[BridgeRule, ...]:
        src, tgt = self.platforms[m.source].ontology, self.platforms[m.target].ontology
        for n, rule in enumerate(m.rules, 1):
            for side, iri, ont in (("source", rule.source, src), ("target", rule.target, tgt)):
                want = "individual" if rule.type == "same" else "class"
                found = iri in (ont.individuals if rule.type == "same" else ont.classes)
                if not found:
                    other = "a class" if iri in ont.classes else \
                        "an individual" if iri in ont.individuals else "absent"
                    raise ParseError(f"bridge rule {n} ({rule.type}): {side} <{iri}> is {other} "
                                     f"in {ont.platform} ({ont.file}), expected {article(want)}",
                                     rule.span)
        return m.rules


def _name_index(ont: Ontology) -> NameIndex:
    return NameIndex(ont.platform, ont.prefixes, {
        "feature": ont.features.keys(), "sort": ont.sorts, "object": ont.individuals})


def resolve_spec(p: Platform, spec: TopicSpec) -> ResolvedSpec:
    """Names → IRIs and arity check; well-sortedness is left to the rules."""
    def arg(a: TopicArg) -> ResolvedArg:
        kind: tuple[Kind, ...] = ("object",) if a.kind == "object" else ("sort",)
        return ResolvedArg(a.kind, p.names.resolve(a.name, kind, a.span), a.id_field or "")

    features = []
    for f in spec.features:
        iri = p.names.resolve(f.name, ("feature",), f.span)
        arity = p.ontology.features[iri].arity
        if len(f.args) != arity:
            raise SortError(f"topic {spec.name}: {f.name} takes {arity} argument"
                            f"{'s' if arity != 1 else ''}, not {len(f.args)}", f.span)
        features.append(ResolvedFeature(iri, f.field, tuple(arg(a) for a in f.args)))
    entity = arg(spec.entity) if spec.entity is not None else None
    return ResolvedSpec(spec.name, spec.msgtype, tuple(features), entity)
