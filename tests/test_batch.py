"""`dkreason batch` and `dkreason results`: many runs, each monitored as `monitor` monitors it,
on Dask workers, into a DuckDB results database."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import duckdb
import pytest

from dkreason import KnowledgeManager
from dkreason.batch import find_runs
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.results import Row

REPO = Path(__file__).resolve().parents[1]
FEDERATION = REPO / "examples" / "federation.toml"
FAST = "always (Speed[car1] < 100)"
SPEEDING = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"


def _recording(path: Path, speeds: list[float]) -> Path:
    """JSON lines of car1's speed (topic3), one message a second."""
    path.write_text(
        "".join(
            json.dumps({"topic": "topic3", "time": t, "msg": {"id": 1, "spd": s}}) + "\n"
            for t, s in enumerate(speeds)
        )
    )
    return path


@pytest.fixture
def fleet(tmp_path: Path) -> Path:
    """Three good runs (one too fast), a damaged one and a list naming a missing one."""
    runs = tmp_path / "runs"
    runs.mkdir()
    _recording(runs / "calm.jsonl", [50, 60, 70])
    _recording(runs / "fast.jsonl", [50, 120, 70])
    _recording(runs / "slow.jsonl", [10, 20])
    (runs / "torn.jsonl").write_text(
        '{"topic": "topic3", "time": 0, "msg": {"id": 1, "spd": 5}}\n{"topi'
    )
    (tmp_path / "runs.txt").write_text(
        "# one run a line\nruns/calm.jsonl\nruns/fast.jsonl  # too fast\nruns/slow.jsonl\n"
        "runs/torn.jsonl\nruns/missing.jsonl\n"
    )
    return tmp_path


def _batch(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict[str, Any]]]:
    code = main(["batch", "--config", str(FEDERATION), "--json", "--jobs", "2", *argv])
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    return code, rows


def _monitor(capsys: pytest.CaptureFixture[str], recording: Path, formula: str) -> dict[str, Any]:
    main(["monitor", "--config", str(FEDERATION), "--json", "--source", str(recording), formula])
    events: list[dict[str, Any]] = [json.loads(e) for e in capsys.readouterr().out.splitlines()]
    (verdict,) = [e for e in events if "verdict" in e]
    return verdict


def test_a_batch_gives_each_run_the_verdicts_of_monitor_and_errors_do_not_stop_it(
    fleet: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = fleet / "results.duckdb"
    code, rows = _batch(capsys, "--db", str(db), "--formula", FAST, f"@{fleet / 'runs.txt'}")
    assert code == 1  # violated on one run, although two others failed
    by_run = {r["run"]: r for r in rows}
    assert sorted(by_run) == sorted(
        f"runs/{n}.jsonl" for n in ("calm", "fast", "slow", "torn", "missing")
    )
    for name in ("calm", "fast", "slow"):
        alone = _monitor(capsys, fleet / "runs" / f"{name}.jsonl", FAST)
        row = by_run[f"runs/{name}.jsonl"]
        word = {True: "held", False: "violated", None: "undecided"}[alone["verdict"]]
        assert (row["verdict"], row["time"], row["t"], row["witness"]) == (
            word,
            alone["time"],
            alone["t"],
            alone["witness"],
        )
        assert row["error"] is None and row["messages"] > 0
    assert by_run["runs/fast.jsonl"]["verdict"] == "violated"
    assert by_run["runs/missing.jsonl"]["verdict"] == "error"
    assert "no such" in by_run["runs/missing.jsonl"]["error"]
    assert by_run["runs/missing.jsonl"]["t"] is None
    assert by_run["runs/torn.jsonl"]["verdict"] == "error" and by_run["runs/torn.jsonl"]["error"]

    with duckdb.connect(str(db), read_only=True) as con:  # the database, read back as it is
        found = con.execute(
            "SELECT run, verdict FROM verdicts WHERE formula = ? ORDER BY run", [FAST]
        ).fetchall()
        (formulas,) = con.execute("SELECT formulas FROM batches").fetchone()  # type: ignore[misc]
    assert dict(found) == {r: by_run[r]["verdict"] for r in by_run}
    assert json.loads(formulas) == [FAST]

    assert main(["results", "--db", str(db)]) == 0  # the summary, then the violated runs
    out = capsys.readouterr().out
    assert FAST in out and "VIOLATED at t+1 s: runs/fast.jsonl" in out
    assert main(["results", "--db", str(db), "--verdict", "error", "--json"]) == 0
    errors = [json.loads(line)["run"] for line in capsys.readouterr().out.splitlines()]
    assert errors == ["runs/missing.jsonl", "runs/torn.jsonl"]
    assert main(["results", "--db", str(db), "--parquet", str(fleet / "out.parquet")]) == 0
    with duckdb.connect() as con:
        assert con.execute(f"SELECT count(*) FROM '{fleet / 'out.parquet'}'").fetchone() == (5,)
    assert main(["results", "--db", str(db), "--batch", "nope"]) == 2
    assert "no batch 'nope'" in capsys.readouterr().err


def test_constraint_violations_are_counted_per_kind_and_fail_the_batch_when_asked(
    fleet: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One message a second where --period 0.5 expects two: every interval is a violation
    (2 in calm, 1 in slow), counted once a run; exit 1 only with --fail-on-constraint."""
    argv = [
        "batch",
        "--config",
        str(FEDERATION),
        "--jobs",
        "1",
        "--db",
        str(fleet / "results.duckdb"),
        "--period",
        "0.5",
        "--formula",
        FAST,
        "--formula",
        "always (Speed[car1] >= 0)",
        str(fleet / "runs" / "calm.jsonl"),
        str(fleet / "runs" / "slow.jsonl"),
    ]
    assert main(argv) == 0
    assert "stream constraint violations: 3 sample_period" in capsys.readouterr().out
    assert main([*argv, "--fail-on-constraint"]) == 1


def test_a_folder_is_searched_and_a_ros2_bag_folder_is_one_run(
    traffic: Path, tmp_path: Path
) -> None:
    (tmp_path / "day1").mkdir()
    shutil.copytree(traffic, tmp_path / "day1" / "bag")
    (tmp_path / "day1" / "notes.txt").write_text("not a recording")
    (tmp_path / "day1" / "old.mcap").write_bytes(b"")
    runs = find_runs([str(tmp_path / "day1")])
    assert [r.name for r in runs] == [
        str(tmp_path / "day1" / "bag"),
        str(tmp_path / "day1" / "old.mcap"),
    ]
    with pytest.raises(DkError, match="no run found"):
        find_runs([])
    with pytest.raises(DkError, match="missing.txt"):
        find_runs([f"@{tmp_path / 'missing.txt'}"])


def test_resume_monitors_only_the_runs_an_interrupted_batch_left(fleet: Path) -> None:
    km = KnowledgeManager.from_config(FEDERATION)
    db = fleet / "results.duckdb"
    source = [f"@{fleet / 'runs.txt'}"]
    seen: list[list[Row]] = []

    def interrupt(rows: list[Row]) -> None:
        seen.append(rows)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        km.batch(source, FAST, jobs=1, db=db, on_run=interrupt)
    started: list[tuple[int, int]] = []
    done = km.batch(
        source,
        FAST,
        jobs=1,
        db=db,
        resume=True,
        on_start=lambda _b, _d, t, s: started.append((t, s)),
    )
    assert started == [(3, 2)]
    assert len(done.rows) == 3 and done.skipped == 2 and done.runs == 5
    assert done.status == 1  # the whole batch: fast.jsonl, monitored before the interruption
    assert sum(done.counts[FAST].values()) == 5
    again = km.batch(source, FAST, jobs=1, db=db, resume=True)
    assert (again.batch_id, again.rows) == (done.batch_id, ())


def test_a_batch_runs_beside_another_cluster_on_dasks_default_port(fleet: Path) -> None:
    """Two batches at once (another user's, or two test workers) each start a local cluster:
    none takes Dask's fixed dashboard port 8787, which the other may hold."""
    taken = socket.socket()
    try:
        taken.bind(("0.0.0.0", 8787))
        taken.listen()
    except OSError:  # held already: the case itself
        pass
    try:
        done = KnowledgeManager.from_config(FEDERATION).batch(
            [str(fleet / "runs" / "fast.jsonl")], FAST, jobs=1, db=fleet / "r.duckdb"
        )
    finally:
        taken.close()
    assert [row.verdict for row in done.rows] == ["violated"]


def test_diff_lists_the_verdicts_a_changed_spec_and_recording_changed(
    fleet: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for part in ("ontologies", "specs"):
        shutil.copytree(REPO / part, fleet / part)
    (fleet / "config").mkdir()
    shutil.copy(FEDERATION, fleet / "config")
    db = fleet / "results.duckdb"
    argv = ["batch", "--config", str(fleet / "config" / "federation.toml"), "--db", str(db)]
    argv += ["--jobs", "1"]
    argv += ["--formula", FAST, f"@{fleet / 'runs.txt'}"]
    assert main(argv) == 1
    time.sleep(0.01)  # a new modification time for the changed recording
    _recording(fleet / "runs" / "calm.jsonl", [50, 160])
    specs = fleet / "specs" / "platform1.sslt"
    specs.write_text(specs.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    assert main(argv) == 1
    capsys.readouterr()
    with duckdb.connect(str(db), read_only=True) as con:
        first, second = (
            r[0] for r in con.execute("SELECT batch_id FROM batches ORDER BY started").fetchall()
        )
    assert main(["results", "--db", str(db), "--diff", first, second, "--json"]) == 0
    changes = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert changes == [
        {"run": "runs/calm.jsonl", "formula": FAST, "before": "held", "after": "violated"}
    ]


def test_bad_input_to_the_batch_as_a_whole_is_one_line_and_exit_2(
    fleet: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["batch", "--config", str(FEDERATION), "--db", str(fleet / "r.duckdb")]
    assert main([*base, "--formula", FAST, f"@{fleet / 'nope.txt'}"]) == 2
    assert main([*base, "--formula", "always (Speed[car1] <", str(fleet / "runs")]) == 2
    assert main([*base, str(fleet / "runs")]) == 2  # no formula
    with pytest.raises(SystemExit) as exc:
        main([*base, "--formula", FAST, "--timeout", "0", str(fleet / "runs")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 4 and all("error" in line for line in err)


# ---- on a running Dask cluster ---------------------------------------------------------------


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """`dask scheduler` and two `dask worker` processes on loopback."""
    address = f"tcp://127.0.0.1:{_port()}"

    def start(command: str, *argv: str) -> subprocess.Popen[bytes]:  # `dask scheduler` etc.
        return subprocess.Popen(
            [sys.executable, "-m", f"distributed.cli.{command}", *argv],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            cwd=tmp_path,
        )

    procs = [start("dask_scheduler", "--host", "127.0.0.1", "--port", address.rpartition(":")[2])]
    procs += [
        start("dask_worker", address, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1")
        for _ in range(2)
    ]
    from distributed import Client

    try:
        with Client(address, timeout="60s") as client:  # type: ignore[no-untyped-call]
            client.wait_for_workers(2, timeout=60)
        yield address, procs
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_a_running_cluster_runs_the_batch_and_a_killed_worker_loses_no_run(
    fleet: Path, traffic: Path, cluster: tuple[str, list[subprocess.Popen[bytes]]]
) -> None:
    address, procs = cluster
    for n in range(6):
        shutil.copytree(traffic, fleet / "bags" / f"run{n}")
    km = KnowledgeManager.from_config(FEDERATION)
    killed = threading.Event()

    def kill_one(rows: list[Row]) -> None:
        if not killed.is_set():
            killed.set()
            os.kill(procs[1].pid, signal.SIGKILL)  # a worker dies mid-batch

    done = km.batch(
        [str(fleet / "bags")], SPEEDING, scheduler=address, db=fleet / "r.duckdb", on_run=kill_one
    )
    assert killed.is_set()
    assert sorted(r.run for r in done.rows) == sorted(
        str(fleet / "bags" / f"run{n}") for n in range(6)
    )
    assert {r.verdict for r in done.rows} == {"violated"}  # each run monitored to its verdict
    assert procs[0].poll() is None  # the cluster is not shut down by the batch
