"""Thesis chapter 7 reproduced: the Knowledge Manager timed phase by phase beside the thesis.

For test cases 1.1, 1.2, 1.3, 2.1, 2.2, 3 and 4 at every x-axis point of tables 7.1–7.7 this
writes the seeded workload (src/dkreason/workloads.py) as ordinary OWL/SSL_T files, then
times, through the public API a user calls:

- preprocessing: `KnowledgeManager.from_config` (ontology and specs loaded, closures included);
- extracting: parsing the formula; checking: its features against the ontology;
- matching: expanding quantifiers and asking the rules for every feature's topics at once;
- building: the stream request.

Every point runs in fresh processes (`--processes`, default 3; the median of them is shown),
as a user's command does: the load is timed cold (the files parsed, none of them cached; the
grammars' tables from lark's cache, as on any machine that ran dkreason before), then the
first formula after it, then `--runs` more (their median is "later").  Wall and CPU time
both.  Tables print in the thesis' layout with its figures beside ours; the target is
per-formula work (extracting + checking + matching + building), first formula included, at
most 0.1% of the thesis' same phases.  `--sorts` is the second reading of the workloads: the
further relevant specs (2.2, 3) read `some B` instead of naming objects.  `--growth` times the
9-feature workload at scales 1, 10 and 100 and prints each phase's fitted growth exponent
(1 = linear).

    python -m benchmarks.chapter7 [--runs 7] [--processes 3] [--cases 1.1,4] [--sorts]
                                  [--growth] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from dkreason import KnowledgeManager
from dkreason.check import check_formula
from dkreason.expand import expand
from dkreason.match import match
from dkreason.parse.formula import parse_formula
from dkreason.request import build_request
from dkreason.workloads import COLUMNS, SETUPS, Workload, write

PHASES = (
    "Preprocessing",
    "Extracting features",
    "Checking features",
    "Matching topic specs",
    "Building the request",
)
FORMULA_PHASES = PHASES[1:]
TARGET_SHARE = 0.001
OUT = Path(__file__).resolve().parents[1] / "out" / "chapter7"


@dataclass(frozen=True)
class Case:
    """One thesis table: its x axis, its figures (ms) and how to build a point's workload."""

    name: str
    title: str
    axis: str
    xs: tuple[str, ...]
    thesis: dict[str, tuple[int, ...]]  # Preprocessing, Extracting, Checking, Matching
    point: Callable[[int, int], tuple[Workload, str]]  # (column index, scale) -> setup


_PRE = "Preprocessing"
_KEYS = {
    "preprocessing": _PRE,
    "extracting": "Extracting features",
    "checking": "Checking features",
    "matching": "Matching topic specs",
}


def _cases() -> list[Case]:
    """The thesis' tables (thesis.toml) joined to the workload each point needs."""
    tables = tomllib.loads((Path(__file__).parent / "thesis.toml").read_text(encoding="utf-8"))
    assert {n: len(t["x"]) for n, t in tables.items()} == COLUMNS, "thesis.toml vs chapter7"
    return [
        Case(
            name,
            t["title"],
            t["axis"],
            tuple(t["x"]),
            {_KEYS[k]: tuple(t[k]) for k in _KEYS},
            SETUPS[name],
        )
        for name, t in tables.items()
    ]


CASES = _cases()


def time_formula(km: KnowledgeManager, text: str) -> dict[str, float]:
    """One run of the per-formula phases, in ms, exactly as `check_formula` chains them."""
    kb = km.kb
    t0 = time.perf_counter()
    parsed = parse_formula(text)
    t1 = time.perf_counter()
    checked = check_formula(kb, parsed)
    t2 = time.perf_counter()
    ground = list(expand(kb, parsed, checked).ground)
    matches, rejected = match(kb, ground)
    t3 = time.perf_counter()
    request = build_request(kb, text, ground, matches, rejected)
    t4 = time.perf_counter()
    missing = [f for f in request.features if not f.topics]
    if missing:
        raise SystemExit(f"chapter7: workload broken, no topic for {missing[0].feature}")
    return dict(
        zip(
            FORMULA_PHASES,
            ((t1 - t0) * 1e3, (t2 - t1) * 1e3, (t3 - t2) * 1e3, (t4 - t3) * 1e3),
            strict=True,
        )
    )


FIRST, FIRST_CPU, LATER_CPU, PRE_CPU = (
    "First formula",
    "First formula CPU",
    "Later formula CPU",
    "Preprocessing CPU",
)


def one_process(config: Path, text: str, runs: int) -> dict[str, float]:
    """What one fresh process sees (`--point`): a cold load, the first formula after it, and
    the median phases of `runs` later ones; ms, wall unless named CPU."""
    c0, t0 = time.process_time(), time.perf_counter()
    km = KnowledgeManager.from_config(config)
    out = {_PRE: (time.perf_counter() - t0) * 1e3, PRE_CPU: (time.process_time() - c0) * 1e3}
    c0 = time.process_time()
    out[FIRST] = per_formula(time_formula(km, text))
    out[FIRST_CPU] = (time.process_time() - c0) * 1e3
    samples, cpu = [], []
    for _ in range(runs):
        c0 = time.process_time()
        samples.append(time_formula(km, text))
        cpu.append((time.process_time() - c0) * 1e3)
    for phase in FORMULA_PHASES:
        out[phase] = statistics.median(s[phase] for s in samples)
    out[LATER_CPU] = statistics.median(cpu)
    return out


def measure(w: Workload, text: str, runs: int, processes: int, folder: Path) -> dict[str, float]:
    """Median over `processes` fresh processes of every figure of `one_process`."""
    config = write(w, folder)
    cache = folder / "cache"  # the grammars' tables stay; parsed platforms and views never do
    env = os.environ | {"DKREASON_CACHE": str(cache)}
    seen = []
    for _ in range(processes):
        for entry in [*cache.glob("platform-*"), *cache.glob("views-*")]:
            entry.unlink()
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "benchmarks.chapter7",
                "--point",
                str(config),
                "--formula",
                text,
                "--runs",
                str(runs),
            ],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        if done.returncode:
            raise SystemExit(f"chapter7: a point failed: {done.stderr.strip()[-500:]}")
        seen.append(json.loads(done.stdout))
    return {k: statistics.median(s[k] for s in seen) for k in seen[0]}


def per_formula(figures: dict[str, float]) -> float:
    return sum(figures[p] for p in FORMULA_PHASES)


def thesis_per_formula(case: Case, i: int) -> float:
    return sum(case.thesis[p][i] for p in FORMULA_PHASES if p in case.thesis)


def run_case(
    case: Case, scale: int, runs: int, processes: int, root: Path, sorts: bool
) -> list[dict[str, float]]:
    results = []
    for i in range(len(case.xs)):
        w, text = case.point(i, scale)
        if sorts:
            w = replace(w, sort_share=1.0)
        results.append(measure(w, text, runs, processes, root / f"case{case.name}-{i}"))
    return results


def _fmt(ms: float) -> str:
    return f"{ms:.0f}" if ms >= 100 else f"{ms:.3g}"


def table(case: Case, results: list[dict[str, float]]) -> list[list[str]]:
    """Rows in the thesis' layout: each phase as thesis / ours, then per-formula and its share."""
    rows = [[case.axis or "Formula", *case.xs]]
    for phase in PHASES:
        if phase in case.thesis:
            rows.append([f"{phase} (thesis)", *(str(v) for v in case.thesis[phase])])
        rows.append([f"{phase} (ours)", *(_fmt(r[phase]) for r in results)])
    rows.append(
        [
            "Per formula (thesis)",
            *(str(round(thesis_per_formula(case, i))) for i in range(len(case.xs))),
        ]
    )
    rows.append(["Per formula, later (ours)", *(_fmt(per_formula(r)) for r in results)])
    rows.append(["Per formula, first (ours)", *(_fmt(r[FIRST]) for r in results)])
    rows.append(
        [
            "CPU: later / first (ours)",
            *(f"{_fmt(r[LATER_CPU])}/{_fmt(r[FIRST_CPU])}" for r in results),
        ]
    )
    rows.append(
        [
            "Ours / thesis, later",
            *(f"{per_formula(r) / thesis_per_formula(case, i):.3%}" for i, r in enumerate(results)),
        ]
    )
    rows.append(
        [
            "Ours / thesis, first",
            *(f"{r[FIRST] / thesis_per_formula(case, i):.3%}" for i, r in enumerate(results)),
        ]
    )
    rows.append(
        [
            "Ours / thesis, preprocessing",
            *(f"{r[_PRE] / case.thesis[_PRE][i]:.0%}" for i, r in enumerate(results)),
        ]
    )
    return rows


def plain(rows: list[list[str]]) -> str:
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    return "\n".join(
        "  ".join(
            cell.rjust(w) if c else cell.ljust(w)
            for c, (cell, w) in enumerate(zip(r, widths, strict=True))
        )
        for r in rows
    )


def markdown(rows: list[list[str]]) -> str:
    lines = [
        "| " + " | ".join(rows[0]) + " |",
        "|" + "|".join(["---"] + ["---:"] * (len(rows[0]) - 1)) + "|",
    ]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines)


def plot(case: Case, results: list[dict[str, float]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = list(range(len(case.xs)))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(
        xs,
        [thesis_per_formula(case, i) for i in xs],
        "o-",
        color="tab:red",
        label="thesis, per formula",
    )
    ax.plot(xs, case.thesis[_PRE], "s--", color="tab:red", alpha=0.5, label="thesis, preprocessing")
    ax.plot(
        xs, [per_formula(r) for r in results], "o-", color="tab:blue", label="dkreason, per formula"
    )
    ax.plot(
        xs,
        [r[_PRE] for r in results],
        "s--",
        color="tab:blue",
        alpha=0.5,
        label="dkreason, preprocessing",
    )
    ax.plot(
        xs,
        [thesis_per_formula(case, i) * TARGET_SHARE for i in xs],
        ":",
        color="grey",
        label="target: 0.1% of thesis",
    )
    ax.set_yscale("log")
    ax.set_xticks(xs, case.xs)
    ax.set_xlabel(case.axis or "formula")
    ax.set_ylabel("ms (log scale)")
    ax.set_title(f"Test case {case.name}: {case.title.lower()}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def growth(scales: list[int], runs: int, processes: int, root: Path) -> list[list[str]]:
    """The 9-feature workload (table 7.1's last point) grown by each scale; fitted exponents."""
    figures = {
        s: measure(*SETUPS["1.1"](7, s), runs, processes, root / f"growth-{s}") for s in scales
    }
    header = ["Phase (ms)", *(f"scale {s}" for s in scales), "exponent"]
    rows = [header]
    first, last = scales[0], scales[-1]
    for phase in (*PHASES, "Per formula", FIRST):
        values = [
            per_formula(figures[s]) if phase == "Per formula" else figures[s][phase] for s in scales
        ]
        k = math.log(values[-1] / values[0]) / math.log(last / first)
        rows.append([phase, *(_fmt(v) for v in values), f"{k:.2f}"])
    return rows


def _positive(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return int(text)


def _scales(text: str) -> list[int]:
    return sorted({_positive(x) for x in text.split(",")})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.chapter7", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--runs", type=_positive, default=7, help="runs per formula (median)")
    parser.add_argument(
        "--processes", type=_positive, default=3, help="fresh processes per point (median)"
    )
    parser.add_argument(
        "--sorts",
        action="store_true",
        help="the further relevant specs read `some B` (second reading)",
    )
    parser.add_argument("--point", type=Path, help=argparse.SUPPRESS)  # one process's figures
    parser.add_argument("--formula", help=argparse.SUPPRESS)
    parser.add_argument("--cases", default=",".join(c.name for c in CASES))
    parser.add_argument("--scale", type=_positive, default=1)
    parser.add_argument("--growth", action="store_true", help="also time scales 1, 10, 100")
    parser.add_argument("--scales", type=_scales, default=[1, 10, 100])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    if args.point is not None:
        print(json.dumps(one_process(args.point, args.formula, args.runs)))
        return 0
    wanted = args.cases.split(",")
    unknown = [c for c in wanted if c not in {case.name for case in CASES}]
    if unknown:
        print(f"chapter7: unknown test case {unknown[0]!r}", file=sys.stderr)
        return 2
    if args.growth and len(set(args.scales)) < 2:
        print("chapter7: --scales needs two different scales to fit a growth", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    reading = "further relevant specs over sorts" if args.sorts else "specs name objects"
    report = [
        f"# Thesis chapter 7 reproduced (scale {args.scale}, {reading}; median of "
        f"{args.processes} fresh processes, later formulas the median of {args.runs})\n"
    ]
    worst = 0.0
    with tempfile.TemporaryDirectory(prefix="dkreason-ch7-") as tmp:
        for case in (c for c in CASES if c.name in wanted):
            results = run_case(case, args.scale, args.runs, args.processes, Path(tmp), args.sorts)
            rows = table(case, results)
            print(f"\nTest case {case.name}: {case.title} (scale {args.scale}; ms)")
            print(plain(rows))
            report += [
                f"## Test case {case.name}: {case.title}\n",
                markdown(rows),
                f"\n![test case {case.name}](case{case.name}.png)\n",
            ]
            plot(case, results, args.out / f"case{case.name}.png")
            worst = max(
                worst,
                *(
                    max(per_formula(r), r[FIRST]) / thesis_per_formula(case, i)
                    for i, r in enumerate(results)
                ),
            )
        summary = (
            f"Worst per-formula share of the thesis, first formula included: "
            f"{worst:.3%} (target 0.1%)"
        )
        print(f"\n{summary}")
        report.append(summary + "\n")
        if args.growth:
            rows = growth(args.scales, args.runs, args.processes, Path(tmp))
            print(
                "\nGrowth of the 9-feature workload (200 concepts, 200 individuals, "
                "20 specs at scale 1)"
            )
            print(plain(rows))
            report += ["## Growth of the 9-feature workload\n", markdown(rows), ""]
    (args.out / "report.md").write_text("\n".join(report) + "\n", encoding="utf-8")
    print(f"\nwrote {args.out / 'report.md'} and one plot per test case")
    return 0


if __name__ == "__main__":
    sys.exit(main())
