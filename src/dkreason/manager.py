"""`KnowledgeManager`: the façade of thesis 5.3 over parse → check → expand → match → request."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import DkError, NameError_, Span
from .kb import KnowledgeBase, Platform, check_config, read_mapping, read_platform
from .match import Aside
from .model import FeatureInfo, StreamRequest, TopicSpec
from .parse.config import MappingFiles, PlatformFiles, adapter_paths, read_config
from .plan import Parsed, Plan, plan
from .policy.check import Diagnostic
from .policy.load import check_files
from .request import request

if TYPE_CHECKING:
    from .batch import Batch
    from .explain import Explanation
    from .monitor import MonitorRun
    from .query import Answer, RelationInfo
    from .results import Row
    from .starter import Starter
    from .stream.info import Binding, RecordingInfo
    from .stream.policy import StreamPolicy
    from .stream.sources import Source


def _seconds(value: float | Fraction | str | None, what: str) -> Fraction | None:
    from .inputs.numbers import duration

    return None if value is None else duration(value, what)


class KnowledgeManager:
    """The one front door: everything the CLI does (match, explain, monitor, batch, info,
    plot, init, the knowledge edited), with the CLI's defaults, over one knowledge base
    (`from_config`)."""

    def __init__(self, kb: KnowledgeBase) -> None:
        self.kb = kb

    @classmethod
    def from_config(cls, path: str | Path, live: bool = False) -> KnowledgeManager:
        """`live`: the knowledge at hand for a live monitor (KnowledgeBase.from_config)."""
        return cls(KnowledgeBase.from_config(Path(path), live))

    @property
    def local(self) -> str:
        return self.kb.local

    @property
    def rule_warnings(self) -> list[Diagnostic]:
        """What the static checker warns about in the policy's rule files (one line each with
        `str()`); an error stops the load instead."""
        return self.kb.rule_warnings

    @staticmethod
    def check_rules(
        files: Sequence[str | Path] = (),
        config: str | Path | None = None,
        replace: bool = False,
    ) -> list[Diagnostic]:
        """Every error and warning of a policy, without loading it: the config's policy with
        `files` besides (its constants checked against the knowledge its files hold), or
        without a config `files` added to the shipped policy (`replace`: as the whole
        policy).  What `dkreason rules check` prints."""
        paths = [Path(f) for f in files]
        if config is None:
            return check_files(paths, replace)
        return check_config(read_config(Path(config)), paths)

    def query(self, question: str) -> Answer:
        """The answer to a question in the rules' language (`same_as(P, O, 'uav2')`, a
        conjunction with `&`, or `relevant_topic(Feature, Args, Topic, Filter)`): what
        `dkreason query` prints."""
        from .query import ask

        return ask(self.kb, question)

    def relations(self) -> list[RelationInfo]:
        """Every relation with its columns, kind and rows: `dkreason query --relations`."""
        from .query import relations

        return relations(self.kb)

    def plan(self, formulas: str | Sequence[str | Parsed]) -> Plan:
        """Formulas parsed, checked against the local ontology and expanded, once each."""
        return plan(self.kb, [formulas] if isinstance(formulas, str) else formulas)

    def request(
        self,
        plan: Plan,
        *,
        max_delay: float | Fraction | str | None = None,
        best_source: bool = False,
        degraded: Aside = frozenset(),
    ) -> StreamRequest:
        """The stream request of a plan: every ground feature and the topics to merge (matched
        again whenever it is asked, so it follows the knowledge base as it changes).
        `max_delay` (seconds, or text like "100ms"): the monitor's, past which a topic's
        declared delay makes it irrelevant; `best_source`: each feature's best-ranked topic
        only, not the merge of them all; `degraded`: the (platform, topic)s a monitor set
        aside, their samples having stopped (the policy vetoes them)."""
        limit = _seconds(max_delay, "max_delay")
        made = request(self.kb, plan, max_delay=limit, best_source=best_source, degraded=degraded)
        empty = [q for q, f in enumerate(made.features) if not f.topics]
        if not empty:
            return made
        from .explain import exclusions  # only for a feature left with no topic

        excluded = exclusions(self.kb, list(plan.ground), empty, limit, degraded)
        return replace(made, warnings=(*made.warnings, *excluded)) if excluded else made

    def matcher(self, policy: StreamPolicy) -> Callable[..., StreamRequest]:
        """How a monitor under `policy` matches (a `Monitor`'s `match`, every caller's: the
        offline, live federation and ROS 2 monitors): with its --max-delay and --best-source,
        and the sources it has set aside."""

        def matcher(plan: Plan, *, degraded: Aside = frozenset()) -> StreamRequest:
            return self.request(
                plan,
                max_delay=policy.max_delay,
                best_source=policy.best_source,
                degraded=degraded,
            )

        return matcher

    def check_formula(
        self,
        formula: str,
        *,
        max_delay: float | Fraction | str | None = None,
        best_source: bool = False,
    ) -> StreamRequest:
        """The stream request for `formula`: every ground feature and the topics to merge
        (`max_delay`, `best_source` as `request`'s)."""
        return self.request(self.plan(formula), max_delay=max_delay, best_source=best_source)

    def explain(
        self,
        formula: str,
        feature: str | None = None,
        topic: str | None = None,
        *,
        max_delay: float | Fraction | str | None = None,
        best_source: bool = False,
    ) -> Explanation:
        """Why each topic of the request matched; for a feature without topics, or a named
        topic that was not chosen, the closest candidates and the first condition that failed
        (`max_delay` as `request`'s: a topic it excludes is explained by its declared delay;
        `best_source`: which topic is chosen, and what ranks each other one after it)."""
        from .explain import explain
        from .match import match
        from .request import build_request

        ground = list(self.plan(formula).ground)
        limit = _seconds(max_delay, "max_delay")
        matches, rejected = match(self.kb, ground, limit)
        chosen = (
            build_request(self.kb, formula, ground, matches, rejected, best_source=True).features
            if best_source
            else None
        )
        return explain(self.kb, formula, ground, matches, feature, topic, limit, chosen)

    def monitor(
        self,
        formulas: str | Sequence[str | Parsed],
        source: Source | str | Path | Sequence[str | Path],
        policy: StreamPolicy | None = None,
        *,
        remap: Mapping[str, str] | Sequence[str] | None = None,
        clock: str = "auto",
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
        keep_states: bool = False,
        record: str | Path | None = None,
        clips: str | Path | None = None,
        margin: float | Fraction = 2,
        robustness: bool = False,
        foxglove: str | None = None,
        speed: float | None = None,
        force: bool = False,
    ) -> MonitorRun:
        """A monitoring run exactly as `dkreason monitor` makes it, with its defaults: over
        recordings (`[PLATFORM=]PATH`, one or several: MCAP, ROS 1 bag, rosbag2 folder, JSON
        lines; `remap`, `clock`, `msg` files and `typestore` as the CLI's options) or any
        other `Source` (e.g. a `PushSource`).  Iterate it for verdicts and stream-constraint
        violations as they happen; all times are seconds.  Over ROS recordings, once iterated
        it writes `record` (an MCAP file: the relevant topics byte for byte, the events as
        `foxglove.Log` and JSON) and into the folder `clips` one MCAP file per violation
        (`margin` s around its witness window; `run.written` names them); an existing file is
        refused unless `force`.  `robustness`: each verdict, and each instance's, says by how
        much it held or failed and what decided it (its `robustness`: progress.robustness).
        `foxglove` (`[HOST:]PORT`): the run served to Foxglove over its WebSocket protocol as
        it goes (`run.watcher.url`: where; iterating waits for a subscription), until the run
        is closed.  `speed`: the recordings replayed at that many times their pace (0: at
        once; default 1 with `foxglove`, else 0)."""
        # loaded when first monitoring: `match` and `explain` need no stream readers
        from .monitor import Monitor, MonitorRun
        from .stream.binding import open_recordings
        from .stream.policy import StreamPolicy

        if isinstance(source, str | Path):
            source = [source]
        opened = (
            open_recordings(
                source,
                self.platforms,
                remap=remap,
                clock=clock,
                msg=[Path(m) for m in msg],
                typestore=typestore,
            )
            if isinstance(source, Sequence)
            else source
        )
        policy = policy or StreamPolicy()
        try:
            engine = Monitor(
                self.plan(formulas),
                self.matcher(policy),
                policy,
                keep_states=keep_states,
                robustness=robustness,
            )
            if speed is not None and speed < 0:
                raise DkError(f"speed must be 0 or more (1: real time), not {speed}")
            watcher = None
            if foxglove is not None:
                from .live.viewer import Viewer

                watcher = Viewer(foxglove, [f.feature.key for f in engine.request.features])
        except BaseException:
            opened.close()
            raise
        pace = speed if speed is not None else 1.0 if foxglove is not None else 0.0
        if record is None and clips is None:
            return MonitorRun(engine, opened, speed=pace, watcher=watcher)
        from .live.record import RecordedRun
        from .stream.binding import Recordings

        if not isinstance(opened, Recordings):
            raise DkError("record and clips copy recordings: give paths, not a Source")
        return RecordedRun(
            engine,
            opened,
            None if record is None else Path(record),
            None if clips is None else Path(clips),
            Fraction(margin),
            speed=pace,
            watcher=watcher,
            force=force,
        )

    def info(
        self,
        sources: Sequence[str | Path],
        *,
        fields: bool = False,
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
        timing: bool = False,
    ) -> tuple[list[RecordingInfo], list[Binding]]:
        """What `dkreason info --config` shows: each recording described (`describe`), and
        every spec topic of every platform with the recording topic it binds to."""
        from .stream.info import inspect

        infos, binds = inspect(
            sources,
            self.kb,
            fields=fields,
            msg=[Path(m) for m in msg],
            typestore=typestore,
            timing=timing,
        )
        return infos, binds or []

    @staticmethod
    def describe(
        sources: Sequence[str | Path],
        *,
        fields: bool = False,
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
        timing: bool = False,
    ) -> list[RecordingInfo]:
        """What `dkreason info` shows of recordings (a folder of several: each of them): their
        topics, types, counts, span, clock and damage; with `fields`, each topic's field paths
        a spec can read and their types; with `timing`, each topic's observed rate (median
        and 5th percentile) and delay (header stamp to record time: median and 95th
        percentile), every message read."""
        from .stream.info import inspect

        return inspect(
            sources, fields=fields, msg=[Path(m) for m in msg], typestore=typestore, timing=timing
        )[0]

    def plot(
        self,
        features: Sequence[str],
        source: str | Path | Sequence[str | Path],
        path: str | Path,
        policy: StreamPolicy | None = None,
        *,
        remap: Mapping[str, str] | Sequence[str] | None = None,
        clock: str = "auto",
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
    ) -> None:
        """`dkreason plot`: ground features' values over time (`Speed[car1]`, one panel
        each) drawn from recordings to `path` (.png, .svg or .pdf), as the monitor would see
        them (states made by `policy`)."""
        import re

        from .plot import FORMATS, plot_features

        path = Path(path)
        if path.suffix.lower() not in FORMATS or not path.parent.is_dir():
            raise DkError(f"{path}: name a .png, .svg or .pdf file in an existing directory")
        for f in features:
            if not re.fullmatch(r"\s*\w+\s*\[[\w\s,]*\]\s*", f):
                raise DkError(f"{f!r}: expected a ground feature, like Speed[car1]")
        if not features:
            raise DkError("plot needs a feature, like Speed[car1]")
        options: dict[str, Any] = {
            "remap": remap,
            "clock": clock,
            "msg": msg,
            "typestore": typestore,
        }
        formula = "always (" + " or ".join(f"observed({f})" for f in features) + ")"
        with self.monitor(formula, source, policy, **options) as first:  # the fields' kinds
            kinds = {k: ks[0][2] for k, ks in first.processor.kinds.items() if ks}
        keys = [g.key for g in self.plan(formula).ground]
        strings = [f'{k} == ""' for k in keys if kinds.get(k) == "string"]  # read as strings
        formula = formula[:-1] + "".join(f" or {s}" for s in strings) + ")"
        run = self.monitor(formula, source, policy, keep_states=True, **options)
        for _ in run:  # the states, kept
            pass
        title = f"{', '.join(map(str, keys))} from {run.source.name}"
        plot_features(run, keys, path, title)

    @staticmethod
    def init(
        sources: Sequence[str | Path],
        folder: str | Path,
        *,
        robot: str = "robot",
        topics: Sequence[str] = (),
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
    ) -> Starter:
        """`dkreason init`: a starter model of `robot` from recordings (`topics`: only these)
        written to `folder` as ROBOT.ttl, ROBOT.sslt and ROBOT.toml; `from_config` takes the
        config as it is, its features one per number, boolean or string field."""
        from .starter import init

        return init(
            sources,
            Path(folder),
            robot=robot,
            topics=topics,
            msg=[Path(m) for m in msg],
            typestore=typestore,
        )

    def batch(
        self,
        sources: Sequence[str | Path],
        formulas: str | Sequence[str | Parsed],
        policy: StreamPolicy | None = None,
        *,
        remap: Mapping[str, str] | Sequence[str] | None = None,
        clock: str = "auto",
        msg: Sequence[str | Path] = (),
        typestore: str | None = None,
        jobs: int | None = None,
        scheduler: str | None = None,
        db: str | Path | None = None,
        resume: bool = False,
        timeout: float | None = None,
        on_start: Callable[[str, str | None, int, int], None] | None = None,
        on_run: Callable[[list[Row]], None] | None = None,
    ) -> Batch:
        """Every run of `sources` (recordings, folders searched for them, `@LIST` files)
        monitored as `monitor` monitors one, on `jobs` local worker processes or a running
        Dask `scheduler`; each run's rows written to the results database `db` as it ends.
        `on_start(batch id, dashboard, runs to do, runs skipped)` and `on_run(rows)` report
        progress.  The same rows and batch id as `dkreason batch`."""
        from .batch import Job, find_runs, start
        from .results import DEFAULT_DB
        from .stream.binding import remaps
        from .stream.policy import StreamPolicy

        runs = find_runs([str(s) for s in sources])
        plan = self.plan(formulas)
        policy = policy or StreamPolicy()
        job = Job(
            plan,
            self.matcher(policy)(plan),
            policy,
            tuple(self.platforms),
            tuple((remap if isinstance(remap, Mapping) else remaps(remap or ())).items()),
            clock,
            tuple(str(Path(m).resolve()) for m in msg),
            typestore,
            timeout,
        )
        return start(
            job,
            runs,
            config=self.kb.config.path if self.kb.config else None,
            db=Path(db) if db is not None else DEFAULT_DB,
            resume=resume,
            jobs=jobs,
            scheduler=scheduler,
            on_start=on_start,
            on_run=on_run,
        )

    def stored(self) -> dict[str, tuple[str, int]]:
        """Every stored relation: (told or view, rows) — what `match --stats` prints."""
        return self.kb.engine.sizes()

    # ---- topic specifications ----------------------------------------------------------

    def add_topic(
        self, spec: str | TopicSpec, platform: str | None = None, *, save: bool = True
    ) -> TopicSpec:
        """Add a topic (SSL_T text or a TopicSpec), checked against the ontology; written to
        the platform's specs file unless `save=False` (the knowledge alone changes)."""
        p = self.kb.platform(platform or self.local)
        if isinstance(spec, str):
            from .parse.sslt import parse_text

            parsed = parse_text(spec, "<topic>").specs
            if len(parsed) != 1:
                raise DkError(f"add_topic takes one topic specification, got {len(parsed)}")
            spec = parsed[0]
        self.kb.add_spec(p.name, spec)
        try:
            if save:
                self._persist(p, added=spec)
        except BaseException:
            self.kb.remove_spec(p.name, spec.name)
            raise
        return spec

    def remove_topic(
        self, name: str, platform: str | None = None, *, save: bool = True
    ) -> TopicSpec:
        """Remove a topic; from the specs file too unless `save=False`."""
        p = self.kb.platform(platform or self.local)
        spec = self.kb.remove_spec(p.name, name)
        try:
            if save:
                self._persist(p, removed=name)
        except BaseException:
            self.kb.add_spec(p.name, spec)
            raise
        return spec

    # ---- platforms and mappings: the knowledge edited, no file written ------------------

    def add_platform(
        self,
        name: str,
        ontology: str | Path | Sequence[str | Path],
        specs: str | Path | None = None,
        *,
        reasoning: str = "none",
        skip_imports: bool = False,
        adapters: Sequence[str] = (),
    ) -> None:
        """Add a platform from its files, as a config's `[platforms.NAME]` table names them
        (paths as given; `reasoning="owl-rl"`, `skip_imports` as `imports = "skip"`,
        `adapters` as `adapters = [...]`: shipped names or rule file paths): its specs checked
        against its ontology, the mappings waiting for it made active, its topics used at
        once."""
        if reasoning not in ("none", "owl-rl"):
            raise DkError(f'reasoning must be "none" or "owl-rl", not {reasoning!r}')
        files = (ontology,) if isinstance(ontology, str | Path) else tuple(ontology)
        platform = PlatformFiles(
            name,
            tuple(Path(f) for f in files),
            Path(specs) if specs is not None else None,
            skip_imports=skip_imports,
            reasoning=reasoning,
            adapters=adapter_paths(adapters, Path.cwd()),
        )
        imports = self.kb.config.imports if self.kb.config else {}
        self.kb.add_platform(read_platform(platform, imports))

    def remove_platform(self, name: str) -> None:
        """Forget a platform (not the local one); its mappings wait for it to come back."""
        self.kb.remove_platform(name)

    def add_mapping(self, source: str, target: str, file: str | Path) -> None:
        """Add a COWL bridge-rule file between two platforms (as a config's `[[mappings]]`),
        checked against both ontologies; on error nothing changes."""
        if not {source, target} <= set(self.kb.platforms) or source == target:
            raise DkError(f"a mapping joins two known platforms, not {source!r} and {target!r}")
        self.kb.add_mapping(read_mapping(MappingFiles(source, target, Path(file))))

    def remove_mapping(self, source: str, target: str) -> None:
        self.kb.remove_mapping(source, target)

    def get_topic_specification(self, name: str, platform: str | None = None) -> TopicSpec:
        p = self.kb.platform(platform or self.local)
        if name not in p.specs:
            raise NameError_(
                f"no topic {name!r} on {p.name} (topics: {', '.join(p.specs) or 'none'})",
                Span("<api>"),
            )
        return p.specs[name]

    def list_topic_specifications(self, platform: str | None = None) -> list[TopicSpec]:
        return list(self.kb.platform(platform or self.local).specs.values())

    def list_topics(self, platform: str | None = None) -> list[str]:
        return list(self.kb.platform(platform or self.local).specs)

    def list_sort(self, sort: str, platform: str | None = None) -> list[str]:
        """Local names of the objects of `sort`, subsorts and sameAs included."""
        from .names import local_name

        p = self.kb.platform(platform or self.local)
        iri = p.names.resolve(sort, ("sort",), Span("<sort>"))
        rows = self.kb.engine.query("instance_of", p.name, None, iri)
        return sorted({local_name(str(o)) for _, o, _ in rows})

    def list_sorts(self, platform: str | None = None) -> list[str]:
        """Local names of a platform's sorts (default: the local platform's)."""
        from .names import local_name

        return sorted(
            {local_name(s) for s in self.kb.platform(platform or self.local).ontology.sorts}
        )

    def list_features(self, platform: str | None = None) -> list[FeatureInfo]:
        """Every platform's features (or one platform's), with signatures and where each came
        from: the class pattern or an adapter rule (`dkreason info --config C`)."""
        from .adapt import origin
        from .names import local_name

        return [
            FeatureInfo(
                p.name,
                local_name(iri),
                iri,
                tuple(" ∪ ".join(sorted(map(local_name, s))) for s in sig.arg_sorts),
                origin(p.ontology, iri),
            )
            for p in (
                [self.kb.platform(platform)] if platform else list(self.kb.platforms.values())
            )
            for iri, sig in sorted(p.ontology.features.items(), key=lambda f: local_name(f[0]))
        ]

    def list_objects(self, sort: str | None = None, platform: str | None = None) -> list[str]:
        """Local names of a platform's objects, or of those of `sort` (as `list_sort`)."""
        from .names import local_name

        if sort is not None:
            return self.list_sort(sort, platform)
        return sorted(
            {local_name(o) for o in self.kb.platform(platform or self.local).ontology.individuals}
        )

    @property
    def platforms(self) -> list[str]:
        return list(self.kb.platforms)

    # ---- persistence: the file is edited through its parsed model (parse/specedit.py) ----

    def _persist(
        self, p: Platform, *, added: TopicSpec | None = None, removed: str | None = None
    ) -> None:
        if p.specs_path is not None:
            from .parse.specedit import edit

            edit(p.specs_path, add=added, remove=removed)
