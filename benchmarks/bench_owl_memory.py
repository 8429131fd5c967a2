"""Memory and time of reading an ontology in each OWL syntax, beside Turtle: what a hostile or
merely large file costs before it is knowledge.

Each point is a fresh process that imports the parsers first (the baseline), then reads one
file as a platform's ontology does (parse/owl.py's read_sources: sniffing, the depth check,
py-horned-owl, rdflib) and reports its peak resident memory above the baseline.  Workloads
(dkreason.workloads): 100,000 class assertions; ~200 KB of axioms each nested 60 deep (the
most the depth check lets through); 10,000 nested class expressions (refused: one line).
Target (issue 27): at most 50× the file's size or 100 MB above the baseline, whichever is
larger.

    python -m benchmarks.bench_owl_memory [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dkreason.workloads import assertions_owl, nested_owl

SUFFIX = {"ofn": ".ofn", "omn": ".omn", "omn-chain": ".omn", "owx": ".owx", "turtle": ".ttl"}


def _workloads(folder: Path) -> dict[str, Path]:
    """name → file, written once."""
    files: dict[str, str] = {}
    for syntax in ("ofn", "omn", "owx", "turtle"):
        files[f"100,000 assertions, {syntax}"] = assertions_owl(syntax, 100_000)
    for syntax in ("ofn", "omn", "omn-chain", "owx"):
        per_axiom = len(nested_owl(syntax, 60, 2)) - len(nested_owl(syntax, 60))
        files[f"200 KB 60 deep, {syntax}"] = nested_owl(syntax, 60, 200_000 // per_axiom)
    for syntax in ("ofn", "omn", "omn-chain", "owx"):
        files[f"10,000 deep, {syntax}"] = nested_owl(syntax, 10_000)
    out = {}
    for n, (name, text) in enumerate(files.items()):
        path = folder / f"w{n}{SUFFIX[name.rsplit(', ', 1)[1]]}"
        path.write_text(text, encoding="utf-8")
        out[name] = path
    return out


def _point(path: Path) -> dict[str, object]:
    """`--point`: read one file in this process."""
    import pyhornedowl  # noqa: F401 - loaded before the baseline, as the parse loads it
    import rdflib  # noqa: F401

    from dkreason.errors import DkError
    from dkreason.parse.owl import read_sources

    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    try:
        triples = len(read_sources([path]).graph)
        outcome = f"{triples} triples"
    except DkError as exc:
        outcome = "refused: " + str(exc).split(": ", 1)[-1][:60]
    seconds = time.perf_counter() - start
    peak = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024  # KB → MB
    return {"seconds": seconds, "peak_mb": peak, "outcome": outcome}


def measure() -> dict[str, dict[str, object]]:
    rows: dict[str, dict[str, object]] = {}
    env = os.environ | {"DKREASON_CACHE": "off"}
    with tempfile.TemporaryDirectory(prefix="dkreason-owl-memory-") as tmp:
        for name, path in _workloads(Path(tmp)).items():
            done = subprocess.run(
                [sys.executable, "-m", "benchmarks.bench_owl_memory", "--point", str(path)],
                capture_output=True,
                text=True,
                env=env,
                check=False,
            )
            row: dict[str, object] = {"size_mb": path.stat().st_size / 1e6}
            row |= (
                json.loads(done.stdout)
                if done.returncode == 0
                else {"seconds": None, "peak_mb": None, "outcome": f"exit {done.returncode}"}
            )
            rows[name] = row
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--point", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.point:
        print(json.dumps(_point(Path(args.point))))
        return 0
    rows = measure()
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print("fresh process each, cache off; peak resident memory above the parsers' baseline")
    print(f"{'workload':<34}{'MB':>7}{'s':>7}{'peak MB':>9}{'target':>8}  verdict  outcome")
    for name, r in rows.items():
        size, peak, seconds = r["size_mb"], r["peak_mb"], r["seconds"]
        assert isinstance(size, float)
        target = max(50 * size, 100.0)
        if isinstance(peak, float) and isinstance(seconds, float):
            figures = f"{seconds:>7.1f}{peak:>9.0f}{target:>8.0f}  "
            figures += "met    " if peak <= target else "MISSED "
        else:
            figures = f"{'-':>7}{'-':>9}{target:>8.0f}  -      "
        print(f"{name:<34}{size:>7.2f}{figures}  {r['outcome']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
