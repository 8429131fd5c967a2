"""Whole commands, as a user's shell runs them: wall time of a fresh process, median of ROUNDS.

Beside each other in one run: `python -c pass` and `python -c 'import dkreason'` (the floor),
`dkreason --help`, and `dkreason match` on the thesis federation (examples/federation.toml),
with the parse cache warm (a second run) and off.  Targets (issue 16): --help <= 120 ms, match
<= 250 ms.

    python -m benchmarks.bench_cli [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROUNDS = 9
REPO = Path(__file__).resolve().parents[1]
FEDERATION = REPO / "examples" / "federation.toml"
FORMULA = "forall x in UAV: always (Altitude[x] > 10)"
CLI = [sys.executable, "-m", "dkreason.cli"]


def wall(command: list[str], env: dict[str, str]) -> float:
    """Median seconds of ROUNDS runs of `command` (each must succeed)."""
    times = []
    for _ in range(ROUNDS):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=env)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    match = [*CLI, "match", "--config", str(FEDERATION), FORMULA]
    with tempfile.TemporaryDirectory(prefix="dkreason-cli-") as cache:
        warm = os.environ | {"DKREASON_CACHE": cache}
        subprocess.run(match, check=True, stdout=subprocess.DEVNULL, env=warm)  # fill it
        rows = {
            "python -c pass": (wall([sys.executable, "-c", "pass"], warm), None),
            "python -c 'import dkreason'": (
                wall([sys.executable, "-c", "import dkreason"], warm),
                None,
            ),
            "dkreason --help": (wall([*CLI, "--help"], warm), 0.120),
            "dkreason match (federation, cached)": (wall(match, warm), 0.250),
            "dkreason match (federation, no cache)": (
                wall(match, os.environ | {"DKREASON_CACHE": "off"}),
                0.250,
            ),
        }
    if args.json:
        print(json.dumps({name: seconds for name, (seconds, _) in rows.items()}))
        return 0
    floor = rows["python -c 'import dkreason'"][0]
    print(f"wall time of a fresh process, median of {ROUNDS} (ms)")
    for name, (seconds, target) in rows.items():
        verdict = (
            ""
            if target is None
            else f"  target {target * 1e3:.0f}: {'met' if seconds <= target else 'MISSED'}"
        )
        print(f"  {name:<40}{seconds * 1e3:>8.1f}  {seconds / floor:>5.1f}× import{verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
