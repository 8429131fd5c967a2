"""`dkreason batch` on a fleet of recordings, beside the shell loop it replaces.

Side by side in one run:
- 32 recordings of 60,000 CarMsg messages (bench_monitor's, copied), one formula: the batch
  with `--jobs 1` and `--jobs 2`, in messages per second of the batch's own time (wall time
  less the cluster's start-up: from the batch's start report to its end);
- the same 32 runs as 32 separate `dkreason monitor` processes (the shell loop), in wall time,
  beside the whole `--jobs 1` batch command's wall time;
- the per-run overhead inside a batch: 32 runs of a 10-message recording, `--jobs 1`.

Targets (issue 35): `--jobs 2` >= 1.7x the messages/s of `--jobs 1` (on an otherwise idle
2-core machine); the `--jobs 1` batch <= 0.5x the loop's time; overhead <= 50 ms a run.

    python -m benchmarks.bench_batch [--json] [--runs 32] [--messages 60000]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dkreason import KnowledgeManager
from dkreason.results import Row

from .bench_monitor import recording

REPO = Path(__file__).resolve().parents[1]
FEDERATION = REPO / "examples" / "federation.toml"
FORMULA = "always (Speed[car1] > 60 -> eventually[0, 30] Speed[car1] <= 60)"


def fleet(folder: Path, runs: int, source: Path) -> Path:
    folder.mkdir(parents=True)
    for n in range(runs):
        shutil.copy(source, folder / f"run{n:03}{source.suffix}")
    return folder


def batch(folder: Path, jobs: int, db: Path) -> tuple[float, float, int]:
    """(wall time of the batch's own work, of the whole call, messages read)."""
    km = KnowledgeManager.from_config(FEDERATION)
    began = time.perf_counter()
    started: list[float] = []
    messages = 0

    def on_run(rows: list[Row]) -> None:
        nonlocal messages
        messages += rows[0].messages

    km.batch(
        [str(folder)],
        FORMULA,
        jobs=jobs,
        db=db,
        on_start=lambda *_: started.append(time.perf_counter()),
        on_run=on_run,
    )
    end = time.perf_counter()
    return end - started[0], end - began, messages


def command(folder: Path, jobs: int, db: Path) -> float:
    """The whole `dkreason batch` command, as a shell runs it."""
    began = time.perf_counter()
    subprocess.run(
        [
            sys.executable,
            "-m",
            "dkreason.cli",
            "batch",
            "--config",
            str(FEDERATION),
            "--jobs",
            str(jobs),
            "--db",
            str(db),
            "--formula",
            FORMULA,
            str(folder),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        check=False,
    )
    return time.perf_counter() - began


def loop(folder: Path) -> float:
    """One `dkreason monitor` process a run, one after another."""
    began = time.perf_counter()
    for run in sorted(folder.iterdir()):
        subprocess.run(
            [
                sys.executable,
                "-m",
                "dkreason.cli",
                "monitor",
                "--config",
                str(FEDERATION),
                "--json",
                "--source",
                str(run),
                FORMULA,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            check=False,
        )
    return time.perf_counter() - began


def tiny(path: Path) -> Path:
    path.write_text(
        "".join(
            json.dumps({"topic": "topic3", "time": t, "msg": {"id": 1, "spd": 50}}) + "\n"
            for t in range(10)
        )
    )
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_batch")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--runs", type=int, default=32)
    parser.add_argument("--messages", type=int, default=60_000)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        big = fleet(root / "big", args.runs, recording(args.messages))
        small = fleet(root / "small", args.runs, tiny(root / "tiny.jsonl"))
        one_work, _, messages = batch(big, 1, root / "one.duckdb")
        two_work, _, _ = batch(big, 2, root / "two.duckdb")
        whole = command(big, 1, root / "cli.duckdb")
        shell = loop(big)
        small_work, _, _ = batch(small, 1, root / "small.duckdb")
    figures = {
        "runs": args.runs,
        "messages": messages,
        "jobs1_messages_per_s": round(messages / one_work),
        "jobs2_messages_per_s": round(messages / two_work),
        "jobs2_over_jobs1": round(one_work / two_work, 2),
        "batch_jobs1_s": round(whole, 2),
        "monitor_loop_s": round(shell, 2),
        "batch_over_loop": round(whole / shell, 2),
        "overhead_ms_per_run": round(small_work / args.runs * 1000, 1),
    }
    if args.json:
        print(json.dumps(figures))
        return 0
    print(f"{args.runs} runs, {messages:,} messages in all, formula: {FORMULA}")
    print(f"  --jobs 1: {figures['jobs1_messages_per_s']:>10,} messages/s")
    print(
        f"  --jobs 2: {figures['jobs2_messages_per_s']:>10,} messages/s  "
        f"({figures['jobs2_over_jobs1']}x, target >= 1.7)"
    )
    print(
        f"  batch --jobs 1: {whole:6.2f} s   {args.runs} monitor processes: {shell:6.2f} s  "
        f"({figures['batch_over_loop']}x, target <= 0.5)"
    )
    print(f"  overhead a run (10 messages): {figures['overhead_ms_per_run']} ms (target <= 50)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
