"""`dkreason batch`: every run of a fleet's recordings monitored exactly as `dkreason monitor`
monitors it, on Dask workers (a local cluster of `jobs` processes, or a running cluster's
`scheduler`), each run's verdicts committed to the results database as it finishes.

The formulas are planned and matched once, on the client; a worker binds that plan and its
stream request to one run's recordings, so it needs no knowledge base.  Dask does the rest: a
worker that dies has its run retried once elsewhere (then the run is an `error`, "worker
died"), and nothing of ours schedules, queues or retries.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib.util
import json
import os
import secrets
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import DkError, one_line
from .inputs.files import read_text
from .model import StreamRequest
from .monitor import Monitor, MonitorRun
from .plan import Plan
from .progress import Verdict
from .results import Results, Row
from .stream.binding import is_bag_folder, open_recordings, recordings_in
from .stream.policy import StreamPolicy
from .stream.processor import Violation

_WORDS = {True: "held", False: "violated", None: "undecided"}


@dataclass(frozen=True, slots=True)
class Run:
    """One run: its name as the batch was given it, and its recordings (`[PLATFORM=]PATH`,
    absolute, so any worker that sees the same files can open them)."""

    name: str
    items: tuple[str, ...]

    def digest(self) -> str:
        """The run's files by name, size and modification time (cheap: a resumed batch of a
        thousand runs reads no recording to know which changed)."""
        h = hashlib.sha256()
        for item in self.items:
            path = Path(item.partition("=")[2] if _platform_item(item) else item)
            for f in sorted(path.rglob("*")) if path.is_dir() else [path]:
                with contextlib.suppress(OSError):
                    st = f.stat()
                    h.update(f"{f}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
        return h.hexdigest()[:32]


@dataclass(frozen=True, slots=True)
class Job:
    """What every run shares, sent to each worker once."""

    plan: Plan
    request: StreamRequest
    policy: StreamPolicy
    platforms: tuple[str, ...]
    remap: tuple[tuple[str, str], ...]
    clock: str
    msg: tuple[str, ...]
    typestore: str | None
    timeout: float | None


@dataclass(frozen=True, slots=True)
class Outcome:
    """A run as monitored on a worker: per formula its verdict (or none: the run ended in an
    error before deciding it), with what the row of each needs."""

    verdicts: tuple[tuple[str, Verdict | None], ...]
    violations: tuple[tuple[str, int], ...]
    messages: int
    seconds: float
    error: str | None


def find_runs(sources: Sequence[str]) -> list[Run]:
    """Each SOURCE: a recording, a folder searched for recordings (a ROS 2 bag folder is one
    run), or `@LIST`, a file of runs, one a line (`[PLATFORM=]PATH` items separated by spaces;
    `#` comments; relative paths from the list's folder).  A SOURCE that does not exist is a
    run too: its rows say so."""
    runs: list[Run] = []
    for source in sources:
        if source.startswith("@"):
            listing = Path(source[1:])
            for line in read_text(listing).splitlines():
                items = line.split("#", 1)[0].split()
                if items:
                    runs.append(
                        Run(" ".join(items), tuple(_absolute(i, listing.parent) for i in items))
                    )
            continue
        path = Path(source)
        if path.is_dir() and not is_bag_folder(path):
            runs += [
                Run(str(Path(source) / found.relative_to(path)), (str(found.resolve()),))
                for found in recordings_in(path)
            ]
        else:
            runs.append(Run(source, (_absolute(source, Path.cwd()),)))
    if not runs:
        raise DkError(f"no run found in {', '.join(sources) or 'no source'}")
    unique: dict[str, Run] = {}  # a run named twice is monitored once
    for run in runs:
        unique.setdefault(run.name, run)
    return list(unique.values())


def _platform_item(item: str) -> bool:
    platform, sep, _ = item.partition("=")
    return bool(sep) and "/" not in platform and not Path(item).exists()


def _absolute(item: str, base: Path) -> str:
    if _platform_item(item):
        platform, _, path = item.partition("=")
        return f"{platform}={(base / path).resolve()}"
    return str((base / item).resolve())


def monitor_run(job: Job, run: Run) -> Outcome:
    """One run monitored exactly as `dkreason monitor` would (on a worker): an error is the
    outcome's one line, after whatever the data before it decided; `job.timeout` bounds the
    monitoring from the run's start."""
    began = time.perf_counter()
    decided: dict[str, Verdict] = {}
    violations: Counter[str] = Counter()
    messages, error = 0, None
    deadline = None if job.timeout is None else began + job.timeout

    def tick(_: int) -> None:
        if deadline is not None and time.perf_counter() > deadline:
            raise DkError(f"timed out after {job.timeout:g} s of monitoring")

    try:
        source = open_recordings(
            run.items,
            job.platforms,
            remap=dict(job.remap),
            clock=job.clock,
            msg=[Path(m) for m in job.msg],
            typestore=job.typestore,
        )
        fixed = Monitor(
            job.plan,
            lambda _plan, degraded=frozenset(): job.request.without(degraded),
            job.policy,
        )
        monitored = MonitorRun(fixed, source)
        try:
            for event in monitored.events(tick):
                if isinstance(event, Verdict):  # an update names more instances settled
                    decided[event.formula] = event
                elif isinstance(event, Violation):
                    violations[event.constraint] += 1
        except DkError as exc:
            error = one_line(str(exc))
        messages = monitored.messages
    except DkError as exc:
        error = one_line(str(exc))
    except Exception as exc:  # a reader's own failure: this run's error, not the batch's
        error = one_line(f"{type(exc).__name__}: {exc}")
    return Outcome(
        tuple((f.text, decided.get(f.text)) for f in job.plan.formulas),
        tuple(sorted(violations.items())),
        messages,
        time.perf_counter() - began,
        error,
    )


def rows(batch_id: str, run: Run, digest: str, outcome: Outcome) -> list[Row]:
    """The run's rows: a formula without a verdict is an `error` row when the run failed."""
    out = []
    for formula, v in outcome.verdicts:
        time_ = None if v is None or v.time is None else float(v.time)
        since = None if v is None or v.t is None else float(v.t)
        out.append(
            Row(
                batch_id,
                run.name,
                digest,
                formula,
                "error" if v is None else _WORDS[v.verdict],
                since,
                time_,
                None if v is None else v.witness,
                None if v is None else _instances(v),
                None,
                json.dumps(dict(outcome.violations)),
                outcome.messages,
                round(outcome.seconds, 6),
                outcome.error,
            )
        )
    return out


def _instances(v: Verdict) -> str | None:
    """A quantified formula's instances (JSON), as `monitor --json` gives them."""
    if v.instances is None:
        return None
    return json.dumps([i.to_json() for i in v.instances], ensure_ascii=False)


def died(batch_id: str, run: Run, digest: str, job: Job, why: str) -> list[Row]:
    """The rows of a run whose worker died, twice."""
    outcome = Outcome(tuple((f.text, None) for f in job.plan.formulas), (), 0, 0.0, why)
    return rows(batch_id, run, digest, outcome)


@dataclass(frozen=True, slots=True)
class Batch:
    """What a batch did: its id, the rows written now (a resumed batch's skipped runs keep
    theirs), and the exit status over the whole batch."""

    batch_id: str
    rows: tuple[Row, ...]
    runs: int
    skipped: int
    status: int
    counts: dict[str, dict[str, int]]


def status(counts: dict[str, dict[str, int]]) -> int:
    """1: a formula violated on some run; else 3: a run undecided or failed; else 0."""
    if any(c["violated"] for c in counts.values()):
        return 1
    return 3 if any(c["undecided"] or c["error"] for c in counts.values()) else 0


def new_batch_id() -> str:
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime()) + "-" + secrets.token_hex(3)


def options_of(job: Job) -> dict[str, Any]:
    """The options a batch is resumed with only when they are the same."""
    policy = {f.name: str(getattr(job.policy, f.name)) for f in dataclasses.fields(StreamPolicy)}
    return {
        "policy": policy,
        "remap": [list(r) for r in job.remap],
        "clock": job.clock,
        "msg": list(job.msg),
        "typestore": job.typestore,
        "timeout": job.timeout,
    }


def config_digest(config: Path | None, request: StreamRequest) -> str:
    """The config file and what it makes of the formulas (their stream request): a changed
    spec, rule or ontology that changes a match changes it."""
    h = hashlib.sha256(json.dumps(request.to_json(), sort_keys=True, default=str).encode())
    if config is not None:
        h.update(read_text(config).encode())
    return h.hexdigest()[:32]


@contextlib.contextmanager
def cluster(jobs: int | None, scheduler: str | None) -> Iterator[Any]:
    """A Dask client: on `scheduler` (never shut down here), else on a local cluster of
    `jobs` single-threaded worker processes that retries a dead worker's run once."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise DkError(f"--scheduler {scheduler}: {one_line(str(exc))}") from None
        with client:
            yield client
        return
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        local = LocalCluster(
            n_workers=jobs or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            # any free port: Dask's fixed 8787 may be another cluster's (another batch, or
            # another user's) and its HTTP server (metrics) starts even without a dashboard
            dashboard_address=":0",
            silence_logs=50,
        )
        with local, Client(local) as client:
            yield client


def _has_dashboard() -> bool:
    """Dask draws its dashboard with bokeh, an optional package: without it, no link."""
    return importlib.util.find_spec("bokeh") is not None


def start(
    job: Job,
    runs: Sequence[Run],
    *,
    config: Path | None,
    db: Path,
    resume: bool,
    jobs: int | None,
    scheduler: str | None,
    on_start: Callable[[str, str | None, int, int], None] | None = None,
    on_run: Callable[[list[Row]], None] | None = None,
) -> Batch:
    """A batch begun (or, with `resume`, the latest one with the same config, formulas and
    options continued) and run to its end."""
    from importlib.metadata import version

    texts = [f.text for f in job.plan.formulas]
    options = options_of(job)
    digest = config_digest(config, job.request)
    with Results(db) as results:
        batch_id = results.resumable(digest, texts, options) if resume else None
        if batch_id is None:
            batch_id = new_batch_id()
            results.begin(batch_id, version("dkreason"), digest, texts, options)
        opened = batch_id
        written, skipped = run_batch(
            job,
            runs,
            results,
            batch_id=batch_id,
            jobs=jobs,
            scheduler=scheduler,
            on_start=None if on_start is None else lambda *a: on_start(opened, *a),
            on_run=on_run,
        )
        results.end(batch_id)
        counts = results.counts(batch_id)
    return Batch(batch_id, tuple(written), len(runs), skipped, status(counts), counts)


def run_batch(
    job: Job,
    runs: Sequence[Run],
    results: Any,
    *,
    batch_id: str,
    jobs: int | None,
    scheduler: str | None,
    on_start: Callable[[str | None, int, int], None] | None = None,
    on_run: Callable[[list[Row]], None] | None = None,
) -> tuple[list[Row], int]:
    """Runs not yet recorded in `batch_id` (or whose recordings changed) monitored on the
    cluster, each run's rows written as it finishes.  Returns the rows and how many runs were
    skipped."""
    from distributed import KilledWorker, as_completed

    done = results.done(batch_id)
    digests = {run.name: run.digest() for run in runs}
    todo = [run for run in runs if done.get(run.name) != digests[run.name]]
    written: list[Row] = []
    with cluster(jobs, scheduler) as client:
        if on_start is not None:
            link = client.dashboard_link if scheduler or _has_dashboard() else None
            on_start(link, len(todo), len(runs) - len(todo))
        shared = client.scatter(job, broadcast=True)
        futures = {
            client.submit(monitor_run, shared, run, key=f"dkreason-{batch_id}-{n}", pure=False): run
            for n, run in enumerate(todo)
        }
        for future in as_completed(futures):
            run = futures[future]
            if future.status == "error":
                exc = future.exception()
                why = "worker died" if isinstance(exc, KilledWorker) else one_line(repr(exc))
                made = died(batch_id, run, digests[run.name], job, why)
            else:
                made = rows(batch_id, run, digests[run.name], future.result())
            results.write(made)
            written += made
            if on_run is not None:
                on_run(made)
    return written, len(runs) - len(todo)
