"""Fleet scale: loading and the first formula, each point in a fresh process (seeded).

Three workloads, each loaded cold (no cache), then again from the cache (parsed platforms
kept by dkreason.cache), with the peak memory of the process:

- fleet: 100 platforms × 100 objects, each in its own vocabulary (namespace), 50 specs each
  (5,000, half over sorts), joined to the local platform by 99 COWL bridge files (an `equiv`
  per feature and sort, a `same` for a shared object) — issue 16, item 6;
- sorts: thesis case 2.2 at 10× (500 objects, 5,009 specs, 80% of the further relevant specs
  over `some B`), where the materialized sort × instance view took 61 s and 4.5 GB;
- objects: 10,000 objects and 5,000 specs, of which the formula's nine features match one
  each (9.5 s and 481 MB before; the target for a formula there is 5 ms).

Beside each figure: the issue's target and the figure measured before this design (issue 16).
The live half of item 6: `benchmarks/bench_join.py` (nodes joining) and `bench_live.py`
(samples/s at a latency).

    python -m benchmarks.bench_fleet [--json] [--only fleet,sorts,objects]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dkreason.workloads import Workload, nine, write

NS = "http://example.org/fleet/p{}#"
FEATURES = ("Battery", "Speed", "Temperature")
# name: (target load s, target cold load s, target MB, before: load s, MB)
TARGETS = {
    "fleet": (None, None, None, None, None),
    "sorts": (2.0, 2.0, 300, 61.0, 4500),
    "objects": (1.0, 3.0, 150, 9.5, 481),
}
FORMULAS = {
    "fleet": "forall r in Drone: always (Battery[r] > 20 and Speed[r] < 10)",
    "sorts": " and ".join(nine()),
    "objects": " and ".join(nine()),
}


def _ontology(p: int, objects: int, rnd: random.Random) -> str:
    ns = NS.format(p)
    out = [
        f"@prefix : <{ns}> .",
        "@prefix owl: <http://www.w3.org/2002/07/owl#> .",
        "@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .",
        f"<{ns[:-1]}> a owl:Ontology .",
        ":arg1 a owl:ObjectProperty .",
        ":UnaryRelation a owl:Class .",
        ":Robot a owl:Class .",
        ":Drone a owl:Class ; rdfs:subClassOf :Robot .",
        ":Rover a owl:Class ; rdfs:subClassOf :Robot .",
    ]
    for f in FEATURES:
        out.append(
            f":{f} a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf "
            f"( :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; "
            f"owl:allValuesFrom :Robot ] ) ] ."
        )
    for j in range(objects):
        out.append(f":r{p}_{j} a owl:NamedIndividual, :{rnd.choice(('Drone', 'Rover'))} .")
    return "\n".join(out) + "\n"


def _specs(p: int, objects: int, count: int, rnd: random.Random) -> str:
    lines = []
    for n in range(count):
        f = FEATURES[n % len(FEATURES)]
        if n % 2:
            sort = rnd.choice(("Drone", "Rover", "Robot"))
            lines.append(
                f"topic /p{p}/t{n}:M contains {f}({sort}) = msg.v for some {sort} = msg.id"
            )
        else:
            obj = f"r{p}_{rnd.randrange(objects)}"
            lines.append(f"topic /p{p}/t{n}:M contains {f}({obj}) = msg.v for {obj} = msg.id")
    return "\n".join(lines) + "\n"


def _bridges(p: int) -> str:
    local, remote = NS.format(0), NS.format(p)
    rules = [("equiv", f"{local}{x}", f"{remote}{x}") for x in (*FEATURES, "Robot", "Drone")]
    rules.append(("same", f"{local}r0_{p % 100}", f"{remote}r{p}_0"))
    body = "".join(
        f'  <cowl:bridgeRule cowl:br-type="{t}">\n'
        f"    <cowl:source{'Individual' if t == 'same' else 'Concept'} "
        f'rdf:resource="{a}"/>\n'
        f"    <cowl:target{'Individual' if t == 'same' else 'Concept'} "
        f'rdf:resource="{b}"/>\n  </cowl:bridgeRule>\n'
        for t, a, b in rules
    )
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<cowl:mapping '
        'xmlns:cowl="http://www.itc.it/cowl#" '
        'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n' + body + "</cowl:mapping>\n"
    )


def write_fleet(
    folder: Path, platforms: int = 100, objects: int = 100, specs: int = 50, seed: int = 7
) -> Path:
    """The fleet workload as ordinary files; the config's path."""
    rnd = random.Random(seed)
    folder.mkdir(parents=True, exist_ok=True)
    config = ['local = "p0"']
    for p in range(platforms):
        (folder / f"p{p}.ttl").write_text(_ontology(p, objects, rnd), encoding="utf-8")
        (folder / f"p{p}.sslt").write_text(_specs(p, objects, specs, rnd), encoding="utf-8")
        config += [f"[platforms.p{p}]", f'ontology = "p{p}.ttl"', f'specs = "p{p}.sslt"']
    for p in range(1, platforms):
        (folder / f"p0-p{p}.cowl.xml").write_text(_bridges(p), encoding="utf-8")
        config += [
            "[[mappings]]",
            'source = "p0"',
            f'target = "p{p}"',
            f'file = "p0-p{p}.cowl.xml"',
        ]
    (folder / "fleet.toml").write_text("\n".join(config) + "\n", encoding="utf-8")
    return folder / "fleet.toml"


def _workload(name: str, folder: Path) -> Path:
    if name == "fleet":
        return write_fleet(folder)
    if name == "sorts":
        return write(Workload(500, 500, 0, 5000, 9, nine(), sort_share=0.8), folder)
    return write(Workload(500, 5000, 5000, 0, 5000, nine()), folder)


def one_process(config: Path, formula: str) -> dict[str, float]:
    """`--point`: a load, the first formula after it, the median of the same formula asked
    again; CPU and wall."""
    from dkreason import KnowledgeManager

    c0, t0 = time.process_time(), time.perf_counter()
    km = KnowledgeManager.from_config(config)
    out = {
        "load_s": time.perf_counter() - t0,
        "load_cpu_s": time.process_time() - c0,
        "load_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    times = []
    for _ in range(6):
        t0 = time.perf_counter()
        request = km.check_formula(formula)
        times.append((time.perf_counter() - t0) * 1e3)
        out.setdefault("topics", sum(len(f.topics) for f in request.features))
    out["first_ms"], out["later_ms"] = times[0], statistics.median(times[1:])
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


def measure(name: str, folder: Path) -> dict[str, float]:
    config = _workload(name, folder)
    cache = folder / "cache"
    figures: dict[str, float] = {}
    for run in ("cold", "cached"):
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "benchmarks.bench_fleet",
                "--point",
                str(config),
                "--workload",
                name,
            ],
            capture_output=True,
            text=True,
            env=os.environ | {"DKREASON_CACHE": str(cache)},
            check=False,
        )
        if done.returncode:
            raise SystemExit(f"bench_fleet: {name} failed: {done.stderr.strip()[-500:]}")
        point = json.loads(done.stdout)
        figures.update({f"{run}_{k}": v for k, v in point.items()})
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--only", default=",".join(TARGETS))
    parser.add_argument("--point", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--workload", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.point is not None:
        print(json.dumps(one_process(args.point, FORMULAS[args.workload])))
        return 0
    rows = {}
    with tempfile.TemporaryDirectory(prefix="dkreason-fleet-") as tmp:
        for name in args.only.split(","):
            rows[name] = measure(name, Path(tmp) / name)
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(
        "fresh process per figure; load in s, formulas in ms; memory: the process' peak after "
        "the load (cold, cached) and after the formulas"
    )
    print(
        f"{'workload':<9}{'cold load':>10}{'cached':>8}{'MB cold':>9}{'cached':>8}{'formulas':>9}"
        f"{'first':>9}{'later':>9}{'topics':>8}  targets (cached s, cold s, MB) · before (s, MB)"
    )
    for name, r in rows.items():
        cached, cold, mb, before_s, before_mb = TARGETS[name]
        target = f"{cached}, {cold}, {mb} · {before_s}, {before_mb}" if cold else "-"
        print(
            f"{name:<9}{r['cold_load_s']:>10.2f}{r['cached_load_s']:>8.2f}"
            f"{r['cold_load_mb']:>9.0f}{r['cached_load_mb']:>8.0f}"
            f"{max(r['cold_peak_mb'], r['cached_peak_mb']):>9.0f}{r['cached_first_ms']:>9.1f}"
            f"{r['cached_later_ms']:>9.1f}{r['cached_topics']:>8.0f}  {target}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
