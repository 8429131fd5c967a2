"""What an adapter costs a load: a property-style ontology read through `adapters =
["properties"]`, and a SOSA-style one through `adapters = ["sosa"]`, beside their class-style
equivalent, and the matching of the same formula on each.

Workloads: thesis chapter 7 worlds (dkreason.workloads, section 7.2), their unary and binary
features rewritten as OWL data and object properties (`workloads.property_style`; the ternary
Z stays a feature class, so the property-style ontology mixes both styles), and their unary
ones as classes of observable properties (`workloads.sosa_style`; Y and Z stay classes).  All
are written as Turtle, so the parser is the same; each load is a whole
`KnowledgeManager.from_config` in a fresh process with the cache off, best of ROUNDS; matching
is the workload's formula asked after the load, best of ROUNDS in that process.  Target
(issue 34): an adapted load at most 1.2x the class-style one, matching unchanged.

    python -m benchmarks.bench_adapt [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dkreason.workloads import COLUMNS, SETUPS, property_style, sosa_style, write

ROUNDS = 5
POINTS = [("1.1", COLUMNS["1.1"] - 1), ("1.3", COLUMNS["1.3"] // 2), ("1.3", COLUMNS["1.3"] - 1)]


STYLES = ("classes", "properties", "sosa")


def _configs(folder: Path, case: str, i: int) -> tuple[dict[str, Path], str]:
    """The workload's config in each style (Turtle), by style, and its formula."""
    import rdflib

    workload, formula = SETUPS[case](i, 1)
    text = write(workload, folder).read_text(encoding="utf-8")
    owl = folder / "ch7.owl"
    ontologies = {
        "classes": rdflib.Graph().parse(owl).serialize(format="turtle"),
        "properties": property_style(owl),
        "sosa": sosa_style(owl),
    }
    configs = {}
    for style, ontology in ontologies.items():
        (folder / f"{style}.ttl").write_text(ontology, encoding="utf-8")
        adapters = "" if style == "classes" else f'adapters = ["{style}"]\n'
        configs[style] = folder / f"{style}.toml"
        configs[style].write_text(
            text.replace('"ch7.owl"', f'"{style}.ttl"') + adapters, encoding="utf-8"
        )
    return configs, formula


def _point(config: Path, formula: str) -> dict[str, float]:
    """`--point`: one load and the best of ROUNDS matches, in this process, seconds."""
    from dkreason import KnowledgeManager

    t0 = time.perf_counter()
    km = KnowledgeManager.from_config(config)
    load = time.perf_counter() - t0
    best = float("inf")
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        km.check_formula(formula)
        best = min(best, time.perf_counter() - t0)
    return {"load": load, "match": best}


def measure() -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    env = os.environ | {"DKREASON_CACHE": "off"}
    with tempfile.TemporaryDirectory(prefix="dkreason-adapt-") as tmp:
        for case, i in POINTS:
            folder = Path(tmp) / f"{case}-{i}"
            folder.mkdir()
            configs, formula = _configs(folder, case, i)
            runs: dict[str, list[dict[str, float]]] = {style: [] for style in STYLES}
            for _ in range(ROUNDS):  # interleaved: the styles share the machine's moods
                for style, config in configs.items():
                    done = subprocess.run(
                        [sys.executable, "-m", "benchmarks.bench_adapt", "--point"]
                        + [str(config), formula],
                        capture_output=True,
                        text=True,
                        env=env,
                        check=True,
                    )
                    runs[style].append(json.loads(done.stdout))
            row = {
                f"{style} {what}": min(r[what] for r in found)
                for style, found in runs.items()
                for what in ("load", "match")
            }
            for style in STYLES[1:]:
                row[f"{style} load ratio"] = row[f"{style} load"] / row["classes load"]
            out[f"chapter 7 case {case}, point {i}"] = row
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--point", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.point:
        print(json.dumps(_point(Path(args.point[0]), args.point[1])))
        return 0
    rows = measure()
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"best of {ROUNDS} fresh processes, ms; cache off; target: load ratios <= 1.2")
    print(
        f"{'workload':34} {'classes':>8} {'properties':>11} {'ratio':>6} {'sosa':>6} "
        f"{'ratio':>6} {'match c/p/s':>16}"
    )
    for name, r in rows.items():
        match = "/".join(f"{r[f'{style} match'] * 1e3:.1f}" for style in STYLES)
        print(
            f"{name:34} {r['classes load'] * 1e3:8.0f} {r['properties load'] * 1e3:11.0f} "
            f"{r['properties load ratio']:6.2f} {r['sosa load'] * 1e3:6.0f} "
            f"{r['sosa load ratio']:6.2f} {match:>16}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
