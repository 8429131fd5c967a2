"""Matching with declared stream quality (issue 31) on the thesis chapter 7 workloads.

For the largest point of each test case (src/dkreason/workloads.py, scale 1) this writes the
workload as the thesis has it (no topic declares anything) and with every topic declaring a
seeded rate (1–100 Hz) and delay (0–200 ms), and loads three knowledge bases in one process:
"today", the thesis workload under the policy before declared quality (the shipped rule
files but rules/quality.dl, without match_result's rank rows); "plain", the same workload
under the shipped policy; "declared", the declaring workload under the shipped policy, asked
with --max-delay 150ms (about a quarter of the topics excluded, the rest ranked).  Their
matching (the rules asked for every feature, the request built) is timed in turn, CPU time,
ROUNDS times; medians beside each other.  Target: declared within 1.1x of today.  Ranks and
exclusions are views, derived with the knowledge base and again when --max-delay changes:
"change" is that once-a-monitor cost (declared, from 150 to 200 ms and back, each).

    python -m benchmarks.bench_quality [--json]
"""

from __future__ import annotations

import argparse
import json
import random
import re
import statistics
import tempfile
import time
from fractions import Fraction
from pathlib import Path

from dkreason import KnowledgeManager
from dkreason.match import match
from dkreason.parse.config import shipped_policy
from dkreason.request import build_request
from dkreason.workloads import COLUMNS, SETUPS, write

ROUNDS = 21
VARIANTS = ("today", "plain", "declared")
MAX_DELAY = Fraction(3, 20)
TARGET = 1.1


def declare(config: Path, seed: int = 31) -> None:
    """Every topic of the workload's specs declares a seeded rate and delay."""
    rnd = random.Random(seed)
    specs = config.parent / "ch7.sslt"

    def bracket(found: re.Match[str]) -> str:
        return f"{found.group(0)} [rate {rnd.randint(1, 100)} Hz, delay {rnd.randint(0, 200)}ms]"

    specs.write_text(re.sub(r"(?m)^topic \w+:M", bracket, specs.read_text()), encoding="utf-8")


def today(config: Path) -> None:
    """The config with the policy of before declared quality, as the whole policy."""
    folder = config.parent / "today"
    folder.mkdir()
    for path in shipped_policy():
        if path.name != "quality.dl":
            kept = [ln for ln in path.read_text().splitlines() if "'rank'" not in ln]
            (folder / path.name).write_text("\n".join(kept) + "\n", encoding="utf-8")
    files = ", ".join(f'"today/{p.name}"' for p in sorted(folder.glob("*.dl")))
    config.write_text(
        f"rules = [{files}]\nreplace_rules = true\n" + config.read_text(), encoding="utf-8"
    )


def matching_ms(km: KnowledgeManager, text: str, max_delay: Fraction | None) -> float:
    """One formula's matching and request building, CPU ms."""
    ground = list(km.plan(text).ground)
    t0 = time.process_time()
    matches, rejected = match(km.kb, ground, max_delay)
    build_request(km.kb, text, ground, matches, rejected)
    return (time.process_time() - t0) * 1e3


def change_ms(km: KnowledgeManager) -> float:
    """What a knowledge base pays for a monitor with another --max-delay, CPU ms."""
    t0 = time.process_time()
    km.kb.set_max_delay(Fraction(1, 5))
    km.kb.set_max_delay(MAX_DELAY)
    return (time.process_time() - t0) * 1e3 / 2


def measure(root: Path) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    for case in SETUPS:
        workload, text = SETUPS[case](COLUMNS[case] - 1, 1)
        configs = {name: write(workload, root / case / name) for name in VARIANTS}
        today(configs["today"])
        declare(configs["declared"])
        kms = {name: KnowledgeManager.from_config(c) for name, c in configs.items()}
        times: dict[str, list[float]] = {name: [] for name in VARIANTS}
        for _ in range(ROUNDS):  # in turn, so all see the same machine
            for name, km in kms.items():
                limit = MAX_DELAY if name == "declared" else None
                times[name].append(matching_ms(km, text, limit))
        medians = {k: statistics.median(v) for k, v in times.items()}
        medians["change"] = statistics.median(change_ms(kms["declared"]) for _ in range(5))
        rows.append(
            {
                "case": case,
                "specs": len((root / case / "today" / "ch7.sslt").read_text().splitlines()),
                **{f"{k}_ms": round(v, 2) for k, v in medians.items()},
                "plain_ratio": round(medians["plain"] / medians["today"], 3),
                "declared_ratio": round(medians["declared"] / medians["today"], 3),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = measure(Path(tmp))
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    print(f"matching, CPU ms (declared: --max-delay {float(MAX_DELAY)} s); ratios to today")
    head = f"{'case':<6}{'specs':>7}{'today':>9}{'plain':>9}{'declared':>10}{'change':>8}"
    print(f"{head}{'plain/':>8}{'declared/':>11}  within {TARGET}x")
    for r in rows:
        ok = "yes" if float(r["declared_ratio"]) <= TARGET else "NO"  # type: ignore[arg-type]
        print(
            f"{r['case']:<6}{r['specs']:>7}{r['today_ms']:>9}{r['plain_ms']:>9}"
            f"{r['declared_ms']:>10}{r['change_ms']:>8}{r['plain_ratio']:>8}"
            f"{r['declared_ratio']:>11}  {ok}"
        )


if __name__ == "__main__":
    main()
