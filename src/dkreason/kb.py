"""A knowledge base: every platform's ontology, specs and mappings as facts in one engine.

Built once per config; the matching rules then answer each formula with a few batched queries.
Specs are checked against their ontology as they are loaded or added (thesis 5.3), and mapping
rules against both ontologies they join, so a bad file fails at load time with its line.
"""

from __future__ import annotations

import difflib
import gc
import hashlib
from collections import defaultdict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from functools import cache
from pathlib import Path

from .datalog import Datalog, gc_paused
from .errors import DkError, NameError_, ParseError, SortError, Span
from .facts import (
    STATIC,
    Facts,
    ResolvedArg,
    ResolvedFeature,
    ResolvedSpec,
    merge,
    name_digits,
    ontology_facts,
    rows_of,
    spec_facts,
)
from .inputs.files import read_bytes, resolved
from .model import BridgeRule, IdValue, Mapping_, Ontology, TopicArg, TopicFeature, TopicSpec
from .names import Kind, NameIndex, article, local_name
from .parse.config import Config, MappingFiles, PlatformFiles, read_config, shipped_policy
from .parse.sslt import without_spans
from .policy.check import Diagnostic, Known, check
from .policy.load import read_policy
from .policy.resolve import Names
from .policy.syntax import Row, RuleFile, Value


@dataclass
class Platform:
    ontology: Ontology
    names: NameIndex
    specs: dict[str, TopicSpec] = field(default_factory=dict)
    resolved: dict[str, ResolvedSpec] = field(default_factory=dict)
    specs_path: Path | None = None
    notes: tuple[str, ...] = ()  # warnings from reading its files (imports skipped)
    # each spec's place in the platform's order (as written, added ones last): a request
    # sorts its few topics by it without walking every spec
    rank: dict[str, int] = field(default_factory=dict)
    ranked: int = 0  # ranks given so far

    @property
    def name(self) -> str:
        return self.ontology.platform

    def put(self, spec: TopicSpec, resolved: ResolvedSpec) -> None:
        self.specs[spec.name], self.resolved[spec.name] = spec, resolved
        self.rank[spec.name], self.ranked = self.ranked, self.ranked + 1

    def drop(self, name: str) -> TopicSpec:
        del self.resolved[name], self.rank[name]
        return self.specs.pop(name)


def load_platforms(config: Config) -> dict[str, Platform]:
    """The platforms whose files the config names (a live federation fetches the others)."""
    return {
        files.name: read_platform(files, config.imports)
        for files in config.platforms
        if files.ontology
    }


def read_platform(files: PlatformFiles, imports: dict[str, Path]) -> Platform:
    """A platform's knowledge from its files and what they import: parsed and resolved once,
    then from the cache (dkreason.cache) for as long as every file read keeps its bytes."""
    from . import cache
    from .parse.config import ADAPTER_SCHEMA
    from .parse.owl import ontology_of, read_sources, triples
    from .parse.sslt import is_xml, parse_specs

    specs = files.specs
    xml = specs is not None and is_xml(specs)
    spec_data = read_bytes(specs) if specs else b""
    adapters = (ADAPTER_SCHEMA, *files.adapters) if files.adapters else ()
    rule_data = [(path, read_bytes(path)) for path in adapters]

    def build() -> tuple[Platform, tuple[tuple[str, str | None], ...]]:
        sources = read_sources(files.ontology, imports, files.skip_imports)
        parsed = parse_specs(spec_data, str(specs), xml=xml).specs if specs else ()
        ontology = ontology_of(sources.graph, str(files.ontology[0]), files.name)
        if files.reasoning == "owl-rl":
            from .reason.entail import entail

            ontology = entail(sources.graph, ontology)
        notes: tuple[str, ...] = ()
        if files.adapters:
            from .adapt import adapt

            adapted = adapt(ontology, triples(sources.graph), files.adapters, files.reasoning)
            ontology, notes = adapted.ontology, adapted.warnings
        platform = make_platform(ontology, parsed, specs)
        platform.notes = (*sources.skipped, *notes)
        return platform, (
            *((str(p), cache.digest(d)) for p, d in (*sources.read, *rule_data)),
            *((str(p), None) for p in sources.absent),
        )

    def parsed() -> tuple[Platform, tuple[tuple[str, str | None], ...]]:
        found = build()
        # rdflib's graph and its store refer to each other: the parse leaves cycles.  They are
        # all younger than the last collection, so collecting the youngest generation finds
        # them at the cost of what this parse allocated, not of the whole heap.
        gc.collect(0)
        return found

    parts: list[bytes | str] = [
        files.name,
        *(str(resolved(p)) for p in files.ontology),
        str(specs),
        spec_data,
        str(files.skip_imports),
        files.reasoning,
        *(f"{k}={resolved(v)}" for k, v in sorted(imports.items())),
        *(part for path, data in rule_data for part in (str(resolved(path)), data)),
    ]
    platform, _ = cache.cached("platform", parts, parsed, lambda found: cache.unchanged(found[1]))
    return platform


def load_mappings(config: Config) -> tuple[Mapping_, ...]:
    return tuple(read_mapping(m) for m in config.mappings)


def read_mapping(files: MappingFiles) -> Mapping_:
    """A mapping's bridge rules, read from its COWL file."""
    from .parse.cowl import read_bridge_rules

    return Mapping_(files.source, files.target, str(files.file), read_bridge_rules(files.file))


_CHECK_SLICE = 500


class KnowledgeBase:
    def __init__(
        self,
        local: str,
        platforms: dict[str, Platform],
        mappings: tuple[Mapping_, ...],
        policy: tuple[Path, ...] | None = None,
        config: Config | None = None,
        online: set[str] | None = None,
    ) -> None:
        """`platforms` are those whose knowledge is at hand; a mapping waits until both of its
        platforms are (live federations add them as they appear).  `policy`: the rule files
        (default: the shipped ones).  `online`: the platforms whose topics are used (default:
        all)."""
        self.local = local
        self.platforms = platforms
        self.mappings: tuple[Mapping_, ...] = ()
        self.pending = mappings
        self.config = config
        self.live = online is not None
        self.rederived: list[str] = []  # the views the last change computed again
        self._max_delay: list[Row] = []  # the max_delay rows set_max_delay holds
        self.warnings: list[str] = []
        self.engine = Datalog()
        files = read_policy(
            shipped_policy() if policy is None else policy,
            Names([p.names for p in platforms.values()]),
            config.path.parent if config else None,
        )
        facts = merge(
            STATIC,
            {"local": [(local,)]},
            *(platform_facts(p) for p in platforms.values()),
            self._mapping_facts(),
            {"online": [(p,) for p in platforms if online is None or p in online]},
        )
        # the rule files' warnings (dkreason.policy.check); an error was raised
        self.rule_warnings = self.engine.load(files, known(facts, files))
        self._derive(facts)
        self._warn()

    def _derive(self, facts: Facts) -> None:
        """Assert the facts (emptying `facts` as they go in, so the load's peak holds them
        once), then compute the views and check the specs, or take the views from the cache:
        they, and the checks' verdict, are a function of the facts and the rules alone, so the
        key is their content (a cache hit skips ~2/3 of a load)."""
        from importlib.metadata import version

        from . import cache

        content = hashlib.sha256()
        for pred in list(facts):
            rows = facts.pop(pred)
            if rows:
                content.update(f"{pred}{rows!r}".encode())
                self.engine.assert_rows(pred, rows)
        computed = False

        def compute() -> dict[str, list[Row]]:
            nonlocal computed
            computed = True
            self.engine.materialize()
            for p in self.platforms.values():
                self._check_specs(p, list(p.resolved))
            return self.engine.frozen()

        views = cache.cached(
            "views", [version("pyDatalog"), *self.engine.texts, content.digest()], compute
        )
        if not computed:
            self.engine.restore(views)

    def _mapping_facts(self) -> Facts:
        """Facts of the pending mappings whose platforms are both present, now active."""
        ready = tuple(
            m for m in self.pending if m.source in self.platforms and m.target in self.platforms
        )
        facts = self._facts_of(ready, check=True)
        self.pending = tuple(m for m in self.pending if m not in ready)
        self.mappings += ready
        return facts

    def _facts_of(self, mappings: tuple[Mapping_, ...], check: bool = False) -> Facts:
        return {
            "mapping": [(m.source, m.target) for m in mappings],
            "bridge": [
                (m.source, r.source, m.target, r.target, r.type)
                for m in mappings
                for r in (self._checked(m) if check else m.rules)
            ],
        }

    def _warn(self) -> None:
        # The platforms the policy searches besides the local one (context, which every
        # policy derives: rules/schema.dl).
        joined = {str(r) for _, r in self.engine.query("context", self.local, None)}
        self.warnings = [
            f"platform {name} is joined to {self.local} by no mapping file nor a "
            f"shared vocabulary: its topics are not used"
            for name in self.platforms
            if name != self.local and name not in joined
        ]
        self.warnings += [note for p in self.platforms.values() for note in p.notes]
        self.warnings += [
            f"mapping {m.source}→{m.target} ({m.file}) does not involve the "
            f"local platform {self.local}: unused"
            for m in self.mappings
            if self.local not in (m.source, m.target)
        ]

    @classmethod
    def from_config(cls, path: Path, live: bool = False) -> KnowledgeBase:
        """`live`: for a live monitor, whose config may leave a platform's knowledge to the
        network (no files): the platforms at hand, none online until it appears."""
        with gc_paused():
            kb = cls._load(path, live)
            # The load's heap lives as long as the knowledge base: set it aside, so no
            # collection during the first formulas walks it (parsing collected its garbage).
            gc.freeze()
        return kb

    @classmethod
    def _load(cls, path: Path, live: bool) -> KnowledgeBase:
        config = read_config(path)
        at_hand = load_platforms(config)
        for files in config.platforms:
            if files.name not in at_hand and not live:
                raise ParseError(
                    f"[platforms.{files.name}] has no ontology file: its knowledge "
                    f"comes from the network (dkreason monitor --live)",
                    Span(str(path)),
                )
        online = set[str]() if live else None
        return cls(config.local, at_hand, load_mappings(config), config.rules, config, online)

    # ---- specs -------------------------------------------------------------------------

    def add_spec(self, platform: str, spec: TopicSpec) -> ResolvedSpec:
        """Check `spec` against the platform's ontology and add it; on error nothing changes."""
        p = self.platform(platform)
        if spec.name in p.specs:
            raise DkError(f"topic {spec.name} already exists on {platform}")
        resolved = resolve_spec(p, spec)
        self._change(spec_facts(platform, resolved), self.engine.assert_rows)
        p.put(spec, resolved)
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
        return p.drop(name)

    # ---- a live federation: platforms come and go, objects join sorts ------------------

    def add_platform(self, p: Platform) -> None:
        """Add a platform's knowledge (and the mappings now complete), online."""
        if p.name in self.platforms:
            raise DkError(f"platform {p.name} is already known")
        self.platforms[p.name] = p
        try:
            facts = merge(platform_facts(p), self._mapping_facts(), {"online": [(p.name,)]})
        except DkError:
            del self.platforms[p.name]
            raise
        self._change(facts, self.engine.assert_rows)
        self._check_specs(p, list(p.resolved))
        self._warn()

    def remove_platform(self, name: str) -> Platform:
        """Forget a platform's knowledge (it came back with another ontology); its mappings
        wait for it again."""
        if name == self.local:
            raise DkError(f"{name} is the local platform: its knowledge stays")
        p = self.platform(name)
        gone = tuple(m for m in self.mappings if name in (m.source, m.target))
        self._change(
            merge(
                platform_facts(p),
                self._facts_of(gone),
                {"online": [(name,)] if self.is_online(name) else []},
            ),
            self.engine.retract_rows,
        )
        del self.platforms[name]
        self.mappings = tuple(m for m in self.mappings if m not in gone)
        self.pending += gone
        self._warn()
        return p

    def add_mapping(self, m: Mapping_) -> None:
        """A mapping between two platforms: active at once if both are known (its bridge
        rules checked against both ontologies; on error nothing changes), else when the
        second one comes."""
        if any(
            (x.source, x.target) == (m.source, m.target) for x in (*self.mappings, *self.pending)
        ):
            raise DkError(f"a mapping {m.source}→{m.target} is already known")
        self.pending += (m,)
        try:
            facts = self._mapping_facts()
        except DkError:
            self.pending = tuple(x for x in self.pending if x is not m)
            raise
        self._change(facts, self.engine.assert_rows)
        self._warn()

    def remove_mapping(self, source: str, target: str) -> Mapping_:
        """Forget the mapping from `source` to `target`; its bridge rules no longer count."""
        for m in self.pending:
            if (m.source, m.target) == (source, target):
                self.pending = tuple(x for x in self.pending if x is not m)
                return m
        for m in self.mappings:
            if (m.source, m.target) == (source, target):
                self._change(self._facts_of((m,)), self.engine.retract_rows)
                self.mappings = tuple(x for x in self.mappings if x is not m)
                self._warn()
                return m
        raise DkError(f"no mapping {source}→{target}")

    def set_online(self, name: str, online: bool) -> None:
        """Whether a known platform's topics are used; only what reads `online` is redone."""
        self.platform(name)
        if online != self.is_online(name):
            self._change(
                {"online": [(name,)]},
                self.engine.assert_rows if online else self.engine.retract_rows,
            )

    def set_max_delay(self, delay: Fraction | None) -> None:
        """Match with the monitor's --max-delay (seconds; None: without one), held as the
        `max_delay` fact: the views that read it are derived again only when it changes, so a
        monitor's matches, which all ask with its own, pay nothing for it."""
        rows: list[Row] = [] if delay is None else [(round(delay * 10**9),)]
        if rows != self._max_delay:
            self.rederived = self.engine.thaw(["max_delay"])
            self.engine.retract_rows("max_delay", self._max_delay)
            self.engine.assert_rows("max_delay", rows)
            self.engine.materialize()
            self._max_delay = rows

    def object_id(self, platform: str, iri: str) -> IdValue | None:
        """The id selecting the object in topic messages, by the policy's `object_id`."""
        rows = self.engine.query("object_id", platform, iri, None)
        return rows[0][2] if rows else None

    def is_online(self, name: str) -> bool:
        return bool(self.engine.query("online", name))

    def replace_specs(self, platform: str, specs: list[TopicSpec]) -> tuple[list[str], list[str]]:
        """Make a platform's specs these (changed ones are replaced): (added, removed) names.
        All are checked before anything changes."""
        p = self.platform(platform)
        new = {s.name: s for s in specs}
        for spec in new.values():
            resolve_spec(p, spec)
        removed = [
            n
            for n, s in p.specs.items()
            if n not in new or without_spans(s) != without_spans(new[n])
        ]
        added = [n for n in new if n not in p.specs or n in removed]
        for name in removed:
            self.remove_spec(platform, name)
        for name in added:
            self.add_spec(platform, new[name])
        return added, removed

    def add_object(self, platform: str, name: str, sort: str, id_: IdValue | None = None) -> str:
        """A new object of a sort (an rdf:type axiom); its IRI.  Matching sees it at once."""
        return self.add_objects(platform, [(name, sort, id_)])[0]

    def add_objects(
        self, platform: str, objects: Sequence[tuple[str, str, IdValue | None]]
    ) -> list[str]:
        """Objects of sorts, (name, sort, id) each, added in one step (one name index, one
        re-derivation, however many: a peer may announce thousands at once); their IRIs."""
        p = self.platform(platform)
        facts: Facts = defaultdict(list)
        told = set(p.ontology.types)
        ids = set(p.ontology.ids)
        fresh: set[str] = set()  # objects new in this batch
        added: list[tuple[str, str, IdValue | None]] = []
        iris = []
        for name, sort, id_ in objects:
            sort_iri = p.names.resolve(sort, ("sort",), Span("<api>"))
            ns = sort_iri[: len(sort_iri) - len(local_name(sort_iri))]
            iri = name[1:-1] if name.startswith("<") else ns + name
            iris.append(iri)
            kinds = p.names.kinds(iri)
            if kinds and "object" not in kinds:
                raise NameError_(
                    f"{name!r} is {article(min(kinds))} on {platform}, not an object",
                    Span("<api>"),
                )
            if (iri, sort_iri) in told:
                continue
            if iri in p.ontology.individuals:  # a further sort for its sameAs class
                [(_, _, rep)] = self.engine.query("same_rep", platform, iri, None)
                facts["class_type"].append((platform, rep, sort_iri))
            elif iri in fresh:  # new in this batch, and of another sort
                facts["class_type"].append((platform, iri, sort_iri))
            else:  # a new object: a class of its own
                facts["class_type"].append((platform, iri, sort_iri))
                facts["individual"].append((platform, iri))
                facts["same_rep"].append((platform, iri, iri))
                fresh.add(iri)
                digits = name_digits(local_name(iri))
                if digits is not None:
                    facts["name_digits"].append((platform, iri, digits))
            if id_ is not None and iri not in ids:
                facts["id_property"].append((platform, iri, id_))
                ids.add(iri)
            told.add((iri, sort_iri))
            added.append((iri, sort_iri, id_))
        if added:
            p.ontology = with_objects(p.ontology, added)
            p.names = _name_index(p.ontology)
            self._change(facts, self.engine.assert_rows)
        return iris

    def _change(self, facts: Facts, how: Callable[[str, list[Row]], None]) -> None:
        """Assert or retract facts; only the views that read them are computed again."""
        self.rederived = self.engine.thaw(facts.keys())
        for pred, rows in rows_of(facts):
            how(pred, rows)
        self.engine.materialize()

    def shared_names(self) -> frozenset[str]:
        """Spec topic names (without a leading slash) that more than one platform's specs
        use: a recording's bare name binds to a remote platform only when it is not one."""
        seen: set[str] = set()
        shared: set[str] = set()
        for p in self.platforms.values():
            for name in {n.lstrip("/") for n in p.specs}:
                (shared if name in seen else seen).add(name)
        return frozenset(shared)

    def platform(self, name: str) -> Platform:
        if name not in self.platforms:
            raise DkError(f"unknown platform {name!r} (known: {', '.join(self.platforms)})")
        return self.platforms[name]

    def _check_specs(self, p: Platform, names: list[str]) -> None:
        """Every argument of the named specs fits its feature's signature (rules/signature.dl),
        each distinct use of an object or sort asked once: 100k specs naming a few objects
        cost a few checks."""
        uses: list[Row] = list(
            dict.fromkeys(
                (p.name, f.iri, i, a.kind, a.iri)
                for name in names
                for f in p.resolved[name].features
                for i, a in enumerate(f.args, 1)
            )
        )
        if not uses:
            return
        # Asked in slices: an ask's tables are ~5 KB a use, and a load's peak memory is the
        # heap plus the largest of them (5k specs: 34 MB at once, 4 MB a slice).
        fitting = {
            row
            for at in range(0, len(uses), _CHECK_SLICE)
            for row in self.engine.ask(
                "spec_arg_fits",
                {"spec_arg": uses[at : at + _CHECK_SLICE]},
                p.name,
                None,
                None,
                None,
                None,
            )
        }
        for name in names:
            spec, resolved = with_observations(p, p.specs[name]), p.resolved[name]
            for feature, rfeature in zip(spec.features, resolved.features, strict=True):
                for i, (arg, rarg) in enumerate(zip(feature.args, rfeature.args, strict=True), 1):
                    if (p.name, rfeature.iri, i, rarg.kind, rarg.iri) not in fitting:
                        raise SortError(
                            f"topic {name}: argument {i} of {feature.name} "
                            f"does not fit: {self.misfit(p, rfeature.iri, i, rarg)}",
                            arg.span,
                        )

    def misfit(self, p: Platform, feature: str, i: int, arg: ResolvedArg | str) -> str:
        """Why an object or sort does not fit argument i of a feature, in one phrase."""
        allowed = " or ".join(local_name(s) for s in p.ontology.features[feature].arg_sorts[i - 1])
        fname = local_name(feature)
        if isinstance(arg, str) or arg.kind == "object":
            iri = arg if isinstance(arg, str) else arg.iri
            sorts = self.sorts_of(p.name, iri)
            shown = ", ".join(local_name(s) for s in sorts) or "of no sort"
            return (
                f"{local_name(iri)} is a{'n' if shown[0] in 'AEIOU' else ''} {shown}, "
                f"{fname} needs {allowed}"
            )
        return f"sort {local_name(arg.iri)} is not subsumed by {allowed}, which {fname} needs"

    def sorts_of(self, platform: str, iri: str) -> list[str]:
        """The most specific told sorts of an object, for messages."""
        ont = self.platform(platform).ontology
        told = sorted({c for o, c in ont.types if o == iri})
        return told or sorted(
            {str(s) for (_, _, s) in self.engine.query("is_a", platform, iri, None)}
        )

    # ---- mappings ----------------------------------------------------------------------

    def _checked(self, m: Mapping_) -> tuple[BridgeRule, ...]:
        src, tgt = self.platforms[m.source].ontology, self.platforms[m.target].ontology
        for n, rule in enumerate(m.rules, 1):
            for side, iri, ont in (("source", rule.source, src), ("target", rule.target, tgt)):
                want = "individual" if rule.type == "same" else "class"
                found = iri in (ont.individuals if rule.type == "same" else ont.classes)
                if not found:
                    other = (
                        "a class"
                        if iri in ont.classes
                        else "an individual"
                        if iri in ont.individuals
                        else "absent"
                    )
                    raise ParseError(
                        f"bridge rule {n} ({rule.type}): {side} <{iri}> is {other} "
                        f"in {ont.platform} ({ont.file}), expected {article(want)}",
                        rule.span,
                    )
        return m.rules


def platform_facts(p: Platform) -> Facts:
    """What a platform's ontology and specs tell the engine."""
    return merge(
        {"platform": [(p.name,)]},
        ontology_facts(p.ontology),
        *(spec_facts(p.name, s) for s in p.resolved.values()),
    )


def known(facts: Facts, files: Sequence[RuleFile]) -> Known:
    """The values facts hold, for the rule files' constants check (computed only if a file
    of one's own has constants to check): what the engine is told and the files tell, and the
    nearest to one they do not hold (an IRI: among those with the nearest local name)."""

    @cache
    def values() -> frozenset[Value]:
        told = (v for rows in facts.values() for row in rows for v in row)
        return frozenset(told) | {v for f in files for x in f.facts for v in x.row}

    def near(value: str) -> str | None:
        strings = [v for v in values() if isinstance(v, str) and v]
        if "://" not in value:
            plain = {local_name(v) if "://" in v else v for v in strings}
            found = difflib.get_close_matches(value, plain, 1)
            return found[0] if found else None
        iris = [v for v in strings if "://" in v]
        close = difflib.get_close_matches(local_name(value), {local_name(v) for v in iris}, 1)
        named = [v for v in iris if close and local_name(v) == close[0]]
        found = difflib.get_close_matches(value, named, 1, cutoff=0)
        return found[0] if found else None

    return Known(lambda value: value in values(), near)


def check_config(config: Config, extra: Sequence[Path] = ()) -> list[Diagnostic]:
    """Every error and warning of the config's policy with `extra` rule files besides, checked
    against the knowledge its files hold (no rule is run)."""
    platforms = load_platforms(config)
    rules = (*config.rules, *(p for p in extra if p not in config.rules))
    files = read_policy(rules, Names([p.names for p in platforms.values()]), config.path.parent)
    mappings = load_mappings(config)
    facts = merge(
        STATIC,
        *(platform_facts(p) for p in platforms.values()),
        {
            "bridge": [
                (m.source, r.source, m.target, r.target, r.type) for m in mappings for r in m.rules
            ]
        },
    )
    return check(files, known(facts, files))


def with_objects(ont: Ontology, objects: Iterable[tuple[str, str, IdValue | None]]) -> Ontology:
    """`ont` with more rdf:type axioms (iri, sort, and the object's id if given), in one
    copy: a copy per object made a peer's 50,000 objects cost a billion steps."""
    rows = list(objects)
    return replace(
        ont,
        individuals=ont.individuals | {iri for iri, _, _ in rows},
        types=(*ont.types, *((iri, sort) for iri, sort, _ in rows)),
        ids=dict(ont.ids) | {iri: id_ for iri, _, id_ in rows if id_ is not None},
    )


def make_platform(
    ontology: Ontology, specs: Iterable[TopicSpec], specs_path: Path | None = None
) -> Platform:
    """A platform's knowledge, each spec's names resolved (a bad one raises, naming it)."""
    platform = Platform(ontology, _name_index(ontology), specs_path=specs_path)
    for spec in specs:  # kept as written (`observations of imu1`), resolved as it reads
        platform.put(spec, resolve_spec(platform, spec))
    return platform


def _name_index(ont: Ontology) -> NameIndex:
    return NameIndex(
        ont.platform,
        ont.prefixes,
        {
            "feature": ont.features.keys(),
            "sort": ont.sorts,
            "object": ont.individuals,
            "property": ont.properties,
        },
    )


def with_observations(p: Platform, spec: TopicSpec) -> TopicSpec:
    """`spec` with each `observations of SENSOR` entry as the feature of the one object the
    sensor observes, as the platform's adapters tell it (sosa:observes)."""
    if not any(f.observations for f in spec.features):
        return spec
    features = []
    for f in spec.features:
        if not f.observations:
            features.append(f)
            continue
        sensor = p.names.resolve(f.name, ("object",), f.span)
        seen = sorted({(g, o) for s, g, o in p.ontology.observations if s == sensor})
        if len(seen) != 1:
            shown = ", ".join(f"{local_name(g)}[{local_name(o)}]" for g, o in seen)
            raise NameError_(
                f"topic {spec.name}: sensor {f.name} observes "
                + (
                    f"several features ({shown}): name the feature instead"
                    if seen
                    else "nothing known (its platform's adapters, such as adapters = "
                    '["sosa"], read sosa:observes of a property of an object)'
                ),
                f.span,
            )
        ((feature, obj),) = seen
        arg = TopicArg("object", f"<{obj}>", None, f.span)
        features.append(TopicFeature(f"<{feature}>", f.field, (arg,), f.span))
    return replace(spec, features=tuple(features))


def resolve_spec(p: Platform, spec: TopicSpec) -> ResolvedSpec:
    """Names → IRIs and arity check; well-sortedness is left to the rules."""
    spec = with_observations(p, spec)

    def arg(a: TopicArg) -> ResolvedArg:
        kind: tuple[Kind, ...] = ("object",) if a.kind == "object" else ("sort",)
        return ResolvedArg(a.kind, p.names.resolve(a.name, kind, a.span), a.id_field or "")

    features = []
    for f in spec.features:
        iri = p.names.resolve(f.name, ("feature",), f.span)
        arity = p.ontology.features[iri].arity
        if len(f.args) != arity:
            raise SortError(
                f"topic {spec.name}: {f.name} takes {arity} argument"
                f"{'s' if arity != 1 else ''}, not {len(f.args)}",
                f.span,
            )
        features.append(ResolvedFeature(iri, f.field, tuple(arg(a) for a in f.args)))
    entity = arg(spec.entity) if spec.entity is not None else None
    return ResolvedSpec(spec.name, spec.msgtype, tuple(features), entity, spec.rate, spec.delay)
