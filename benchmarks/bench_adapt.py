"""What an adapter costs a load: a property-style ontology read through `adapters =
["properties"]` beside its class-style equivalent, and the matching of the same formula on both.

Workloads: thesis chapter 7 worlds (dkreason.workloads, section 7.2), their unary and binary
features rewritten as OWL data and object properties (`workloads.property_style`; the ternary
Z stays a feature class, so the property-style ontology mixes both styles).  Both are written
as Turtle, so the parser is the same; each load is a whole `KnowledgeManager.from_config` in a
fresh process with the cache off, best of ROUNDS; matching is the workload's formula asked
after the load, best of ROUNDS in that process.  Target (issue 34): a property-style load at
most 1.2x the class-style one, matching unchanged.

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

from dkreason.workloads import COLUMNS, SETUPS, property_style, write

ROUNDS = 5
POINTS = [("1.1", COLUMNS["1.1"] - 1), ("1.3", COLUMNS["1.3"] // 2), ("1.3", COLUMNS["1.3"] - 1)]


def _configs(folder: Path, case: str, i: int) -> tuple[Path, Path, str]:
    """The workload's config in both styles (Turtle), and its formula."""
    import rdflib

    workload, formula = SETUPS[case](i, 1)
    config = write(workload, folder)
    owl = folder / "ch7.owl"
    (folder / "classes.ttl").write_text(
        rdflib.Graph().parse(owl).serialize(format="turtle"), encoding="utf-8"
    )
    (folder / "properties.ttl").write_text(property_style(owl), encoding="utf-8")
    text = config.read_text(encoding="utf-8")
    classes, properties = folder / "classes.toml", folder / "properties.toml"
    classes.write_text(text.replace('"ch7.owl"', '"classes.ttl"'), encoding="utf-8")
    properties.write_text(
        text.replace('"ch7.owl"', '"properties.ttl"') + 'adapters = ["properties"]\n',
        encoding="utf-8",
    )
    return classes, properties, formula


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
            classes, properties, formula = _configs(folder, case, i)
            runs: dict[str, list[dict[str, float]]] = {"classes": [], "properties": []}
            for _ in range(ROUNDS):  # interleaved: both styles share the machine's moods
                for style, config in (("classes", classes), ("properties", properties)):
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
            row["load ratio"] = row["properties load"] / row["classes load"]
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
    print(f"best of {ROUNDS} fresh processes, ms; cache off; target: load ratio <= 1.2")
    print(f"{'workload':34} {'classes':>9} {'properties':>11} {'ratio':>6} {'match c/p':>14}")
    for name, r in rows.items():
        match = f"{r['classes match'] * 1e3:.1f}/{r['properties match'] * 1e3:.1f}"
        print(
            f"{name:34} {r['classes load'] * 1e3:9.0f} {r['properties load'] * 1e3:11.0f} "
            f"{r['load ratio']:6.2f} {match:>14}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
