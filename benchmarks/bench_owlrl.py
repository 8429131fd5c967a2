"""What `reasoning = "owl-rl"` costs a load, beside rdflib's parse and two OWL RL reasoners.

On W3C SOSA/SSN (a weather station importing SSN through a catalog, tests/data/sosa-ssn) and
on a thesis chapter 7 workload (case 1.3's last point: 200 concepts, 200 individuals), each
in a fresh process with the cache off, best of ROUNDS: rdflib parsing the same files, a
dkreason load without and with reasoning (its own OWL 2 RL rules, parse/owlrl_rules.py), and
the OWL 2 RL closure of the same graph by owlrl (the tests' oracle) and by the `reasonable`
package (Rust; it leaves out property chains).  `make bench` installs both.
Target (issue 15): the OWL RL step adds at most the time rdflib needs to parse the files.

Then the closures that grow with the square of their input (dkreason.workloads.owl_rl_world,
issue 27): a sameAs chain, a transitive chain, a functional property with many values, each a
whole load with reasoning in a fresh process (seconds and peak MB); and a subClassOf chain
1,000 deep without reasoning (refused before its million-row closure is made).  Target: a
sameAs chain of 1,000 loads in under 10 s (it took minutes).

    python -m benchmarks.bench_owlrl [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dkreason.workloads import COLUMNS, SETUPS, owl_rl_world, write

CHAINS = [  # (kind, objects, reasoning)
    ("same-as", 300, "owl-rl"),
    ("same-as", 1000, "owl-rl"),
    ("transitive", 1000, "owl-rl"),
    ("functional", 2000, "owl-rl"),
    ("subclass", 1000, "none"),
]

ROUNDS = 3
REPO = Path(__file__).resolve().parents[1]


def _configs(folder: Path) -> dict[str, tuple[Path, list[Path]]]:
    """Per workload: a config with reasoning on, and the ontology files with their imports."""
    sosa = REPO / "tests" / "data" / "sosa-ssn"
    weather = folder / "weather.toml"
    weather.write_text(
        f'[platforms.w]\nontology = "{sosa / "weather.ttl"}"\nreasoning = "owl-rl"\n',
        encoding="utf-8",
    )
    workload, _ = SETUPS["1.3"](COLUMNS["1.3"] - 1, 1)
    ch7 = write(workload, folder / "ch7")
    ch7.write_text(ch7.read_text() + 'reasoning = "owl-rl"\n', encoding="utf-8")
    return {
        "SOSA/SSN": (weather, [sosa / "weather.ttl", sosa / "ssn.ttl", sosa / "sosa.ttl"]),
        "chapter 7 (1.3, 200/200)": (ch7, [folder / "ch7" / "ch7.owl"]),
    }


def _point(what: str, config: Path, files: list[Path]) -> float:
    """`--point`: one figure in this process, seconds."""
    import rdflib

    if what == "parse":
        t0 = time.perf_counter()
        for f in files:
            rdflib.Graph().parse(f)
        return time.perf_counter() - t0
    if what in ("owlrl", "reasonable"):
        graph = rdflib.Graph()
        for f in files:
            graph.parse(f)
        t0 = time.perf_counter()
        if what == "owlrl":
            import owlrl

            owlrl.DeductiveClosure(
                owlrl.OWLRL_Semantics,
                rdfs_closure=False,
                axiomatic_triples=False,
                datatype_axioms=False,
            ).expand(graph)
        else:
            import reasonable

            reasoner = reasonable.PyReasoner()
            reasoner.from_graph(graph)
            reasoner.reason()
        return time.perf_counter() - t0
    from dkreason import KnowledgeManager

    if what == "load":
        plain = config.with_name(config.stem + "-plain.toml")
        plain.write_text(config.read_text().replace('reasoning = "owl-rl"', ""))
        config = plain
    t0 = time.perf_counter()
    KnowledgeManager.from_config(config)
    return time.perf_counter() - t0


def measure() -> dict[str, dict[str, float | None]]:
    out: dict[str, dict[str, float | None]] = {}
    env = os.environ | {"DKREASON_CACHE": "off"}
    with tempfile.TemporaryDirectory(prefix="dkreason-owlrl-") as tmp:
        for name, (config, files) in _configs(Path(tmp)).items():
            row: dict[str, float | None] = {}
            for what in ("parse", "load", "load+owl-rl", "owlrl", "reasonable"):
                best = None
                for _ in range(ROUNDS):
                    done = subprocess.run(
                        [
                            sys.executable,
                            "-m",
                            "benchmarks.bench_owlrl",
                            "--point",
                            what,
                            str(config),
                            *map(str, files),
                        ],
                        capture_output=True,
                        text=True,
                        env=env,
                        check=False,
                    )
                    if done.returncode:  # `reasonable` not installed: no figure
                        break
                    value = float(done.stdout)
                    best = value if best is None else min(best, value)
                row[what] = best
            out[name] = row
    return out


def _chain_point(config: Path) -> dict[str, float]:
    """`--point chain`: a whole load in this process, seconds and peak MB (refused: what it
    took to say so)."""
    import resource

    from dkreason import KnowledgeManager
    from dkreason.errors import DkError

    start = time.perf_counter()
    with contextlib.suppress(DkError):
        KnowledgeManager.from_config(config)
    seconds = time.perf_counter() - start
    return {
        "seconds": seconds,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def chains() -> dict[str, dict[str, float]]:
    """Per chain workload: seconds and peak MB of a whole load, in a fresh process."""
    out: dict[str, dict[str, float]] = {}
    env = os.environ | {"DKREASON_CACHE": "off"}
    with tempfile.TemporaryDirectory(prefix="dkreason-chains-") as tmp:
        for kind, n, reasoning in CHAINS:
            folder = Path(tmp) / f"{kind}-{n}"
            folder.mkdir()
            (folder / "o.ttl").write_text(owl_rl_world(kind, n), encoding="utf-8")
            config = folder / "c.toml"
            config.write_text(
                f'[platforms.p]\nontology = "o.ttl"\nreasoning = "{reasoning}"\n',
                encoding="utf-8",
            )
            done = subprocess.run(
                [sys.executable, "-m", "benchmarks.bench_owlrl", "--point", "chain", str(config)],
                capture_output=True,
                text=True,
                env=env,
                check=True,
            )
            out[f"{kind} {n} ({reasoning})"] = json.loads(done.stdout)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--point", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.point:
        what, config, *files = args.point
        if what == "chain":
            print(json.dumps(_chain_point(Path(config))))
        else:
            print(_point(what, Path(config), [Path(f) for f in files]))
        return 0
    rows, grown = measure(), chains()
    if args.json:
        print(json.dumps({"workloads": rows, "chains": grown}, indent=1))
        return 0

    def ms(value: float | None) -> str:
        return "-" if value is None else f"{value * 1e3:.0f}"

    print(f"best of {ROUNDS} fresh processes, ms; cache off")
    print(
        f"{'workload':<26}{'parse':>7}{'load':>7}{'+owl-rl':>9}{'step':>7}{'owlrl':>7}"
        f"{'reasonable':>11}  step / parse (target <= 1)"
    )
    for name, r in rows.items():
        step = (r["load+owl-rl"] or 0) - (r["load"] or 0)
        print(
            f"{name:<26}{ms(r['parse']):>7}{ms(r['load']):>7}{ms(r['load+owl-rl']):>9}"
            f"{ms(step):>7}{ms(r['owlrl']):>7}{ms(r['reasonable']):>11}  "
            f"{step / (r['parse'] or 1):.1f}"
        )
    print("\nclosures that grow with the square of their input: a whole load, fresh process")
    for name, figures in grown.items():
        print(f"  {name:<28}{figures['seconds']:>7.1f} s{figures['peak_mb']:>8.0f} MB peak")
    return 0


if __name__ == "__main__":
    sys.exit(main())
