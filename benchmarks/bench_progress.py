"""States per second of the Formula Progressor beside rtamt and reelay, on the same traces.

P1 always (X > 10)                      P4 always not (always[0,300] S > 60)
P2 always (A > 10 and B > C)            P5 always (27-atom conjunction)
P3 always (P -> eventually[0,10] Q)

Each row runs 1, 10 and 100 formulas of that shape at once (thresholds and windows vary, so
nothing is shared but the features) over seeded traces with integer times that satisfy every
formula (no monitor may stop early).  Figures are CPU time, best of ROUNDS runs.  The peers get
their own hand-written past-time forms (rtamt's pastify() mistranslates P3; reelay is past-time
only) and, being slower, fewer states per run: the count is printed with each figure.  Reelay's
atoms compare a field with a constant only, so its P2 trace carries D = B - C precomputed.

Then robustness (issue 30), beside rtamt's discrete-time offline evaluator on the same traces
and formulas (the margin at every state, as rtamt gives it; 1 and 100 formulas):

R1 always (x > c)      R2 always (a > c and b > c)      R3 always (x > c -> eventually[0,w] y > c)

"offline" is dkreason's margin at every state (progress.robustness.margins, as rtamt's);
"monitor" is the Formula Progressor with robustness on, every state stepped and each formula's
margin at its verdict (the end), the states kept only as its windows need (progress.kept).
The traces satisfy every formula (no monitor stops early); then the traced memory of a
1,000,000-state monitor of R3 with robustness at each quarter.

Last, memory over a 1,000,000-state run of P3 (bounded windows): traced memory after 10%, 50%
and 100% of the states.

    python -m benchmarks.bench_progress [--json] [--states N]   (peers: pip install rtamt reelay)
    python -m benchmarks.bench_progress --robustness-only       (the robustness rows alone)
"""

from __future__ import annotations

import argparse
import gc
import json
import random
import time
import tracemalloc
from collections.abc import Callable
from typing import Any, NamedTuple

from dkreason.model import FeatureKey
from dkreason.parse.formula import parse_formula
from dkreason.progress import Progressor
from dkreason.progress.robustness import Signals, margins

ROUNDS = 3
TARGET_RTAMT = 10.0  # at least 10x rtamt on every row
PEER_BUDGET = 0.6  # seconds of peer work per run, to size their traces


class Spec(NamedTuple):
    """One row's k-th formula in each monitor's language (peers need past forms)."""

    ours: str
    rtamt: tuple[str, list[str]]  # formula, its variables
    reelay: str


def spec(kind: str, k: int) -> Spec:
    c, w = 10 - k / 10, 10 + k
    if kind == "P1":
        return Spec(
            f"always (X > {c})", (f"historically(x > {c})", ["x"]), f"historically{{x > {c}}}"
        )
    if kind == "P2":
        return Spec(
            f"always (A > {c} and B > C)",
            (f"historically(a > {c} and b > c)", ["a", "b", "c"]),
            f"historically({{a > {c}}} and {{d > 0}})",
        )
    if kind == "P3":
        return Spec(
            f"always (P -> eventually[0,{w}] Q)",
            (f"historically((once[{w},{w}] (p > 0)) -> once[0,{w}] (q > 0))", ["p", "q"]),
            f"historically((once[{w}:{w}]{{p}}) -> once[0:{w}]{{q}})",
        )
    if kind == "P4":
        return Spec(
            f"always not (always[0,{300 + k}] S > 60)",
            (f"historically(not(historically[0,{300 + k}](spd > 60)))", ["spd"]),
            f"historically(not (historically[0:{300 + k}]{{spd > 60}}))",
        )
    xs = range(27)
    return Spec(
        "always (" + " and ".join(f"X{i} > {c}" for i in xs) + ")",
        ("historically(" + " and ".join(f"x{i} > {c}" for i in xs) + ")", [f"x{i}" for i in xs]),
        "historically(" + " and ".join(f"{{x{i} > {c}}}" for i in xs) + ")",
    )


def specs(kind: str, n: int) -> list[Spec]:
    return [spec(kind, k) for k in range(n)]


def peer_name(feature: str) -> str:
    """Peers' variable names: lower case, and S is `spd` (`s` is a time unit in rtamt)."""
    return "spd" if feature == "S" else feature.lower()


def trace(kind: str, n: int, seed: int = 7) -> list[dict[str, Any]]:
    """Seeded states that satisfy every formula of the row."""
    rnd = random.Random(seed)
    out: list[dict[str, Any]] = []
    last_q = 0
    for t in range(n):
        if kind == "P1":
            out.append({"X": rnd.uniform(11, 20)})
        elif kind == "P2":
            c = rnd.uniform(0, 10)
            out.append({"A": rnd.uniform(11, 20), "B": c + rnd.uniform(0.1, 5), "C": c})
        elif kind == "P3":
            q = rnd.random() < 0.3 or t - last_q >= 8
            last_q = t if q else last_q
            out.append({"P": rnd.random() < 0.5, "Q": q})
        elif kind == "P4":
            out.append({"S": 70 if (t // 150) % 2 else 50})
        else:
            out.append({f"X{i}": rnd.uniform(11, 20) for i in range(27)})
    return out


def best(prepare: Callable[[], Callable[[], int]]) -> tuple[float, int]:
    """(states per CPU second, states) of the best of ROUNDS runs; set-up is not timed."""
    rates = []
    for _ in range(ROUNDS):
        run = prepare()
        gc.collect()
        start = time.process_time()
        states = run()
        rates.append(states / max(time.process_time() - start, 1e-9))
    return max(rates), states


def ours(kind: str, n: int, states: list[dict[str, Any]]) -> tuple[float, int]:
    def prepare() -> Callable[[], int]:
        p = Progressor()
        for f in (x.ours for x in specs(kind, n)):
            p.add(f)

        def run() -> int:
            step = p.step
            for t, values in enumerate(states):
                if step(t, values):
                    raise AssertionError("a benchmark formula was decided early")
            return len(states)

        return run

    return best(prepare)


def with_rtamt(kind: str, n: int, states: list[dict[str, Any]]) -> tuple[float, int] | None:
    try:
        import rtamt
    except ImportError:
        return None
    monitors = []
    for row_spec in specs(kind, n):
        text, variables = row_spec.rtamt
        monitor = rtamt.StlDiscreteTimeSpecification()
        for v in variables:
            monitor.declare_var(v, "float")
        monitor.spec = text
        monitor.parse()
        monitors.append(monitor)
    rows = [[(peer_name(k), float(v)) for k, v in s.items()] for s in states]

    def run() -> int:
        for t, row in enumerate(rows):
            for monitor in monitors:
                monitor.update(t, row)
        return len(rows)

    return best(lambda: run)


def with_reelay(kind: str, n: int, states: list[dict[str, Any]]) -> tuple[float, int] | None:
    try:
        import reelay
    except ImportError:
        return None
    monitors = [reelay.discrete_timed_monitor(pattern=x.reelay) for x in specs(kind, n)]
    rows = []
    for t, s in enumerate(states):
        row = {peer_name(k): v for k, v in s.items()}
        if kind == "P2":
            row["d"] = row["b"] - row["c"]
        row["time"] = t
        rows.append(row)

    def run() -> int:
        for row in rows:
            for m in monitors:
                m.update(row)
        return len(rows)

    return best(lambda: run)


def robust_spec(kind: str, k: int, past: bool = False) -> tuple[str, list[str]]:
    """The k-th formula of a robustness row, in the spelling dkreason and rtamt both read;
    `past`: its past-time form, for rtamt's online monitor."""
    c, w = 10 - k / 10, 5 + k % 10
    if kind == "R1":
        return f"{'historically' if past else 'always'} (x > {c})", ["x"]
    if kind == "R2":
        return f"{'historically' if past else 'always'} (a > {c} and b > c)", ["a", "b", "c"]
    if past:
        return f"historically((once[{w},{w}] (x > {c})) -> once[0,{w}] (y > {c}))", ["x", "y"]
    return f"always (x > {c} -> eventually[0,{w}] (y > {c}))", ["x", "y"]


def robust_trace(n: int, seed: int = 7) -> list[dict[str, float]]:
    """Seeded states that satisfy every formula of the rows (thresholds are at most 10)."""
    rnd = random.Random(seed)
    return [
        {**{v: rnd.uniform(10.5, 20) for v in ("x", "y", "a", "b")}, "c": rnd.uniform(0, 10)}
        for _ in range(n)
    ]


def robust_monitor(kind: str, n: int, rows: list[dict[str, float]]) -> tuple[float, int]:
    """The Progressor with robustness: every state stepped, each margin at the end."""
    states = [{FeatureKey(v): x for v, x in row.items()} for row in rows]

    def prepare() -> Callable[[], int]:
        p = Progressor(robustness=True)
        for k in range(n):
            p.add(robust_spec(kind, k)[0])

        def run() -> int:
            step = p.step
            for t, values in enumerate(states):
                if step(t, values):
                    raise AssertionError("a benchmark formula was decided early")
            if any(v.robustness is None or v.robustness.value is None for v in p.finish()):
                raise AssertionError("a benchmark formula has no margin")
            return len(states)

        return run

    return best(prepare)


def robust_ours(kind: str, n: int, rows: list[dict[str, float]]) -> tuple[float, int]:
    def prepare() -> Callable[[], int]:
        trees = [parse_formula(robust_spec(kind, k)[0]) for k in range(n)]
        trace = [(t, {FeatureKey(v): x for v, x in row.items()}) for t, row in enumerate(rows)]

        def run() -> int:
            signals = Signals(trace)  # the trace's columns read once, for every formula
            for tree in trees:
                margins(tree, signals)
            return len(trace)

        return run

    return best(prepare)


def robust_rtamt(kind: str, n: int, rows: list[dict[str, float]]) -> tuple[float, int] | None:
    try:
        import rtamt
    except ImportError:
        return None
    monitors = []
    for k in range(n):
        text, variables = robust_spec(kind, k)
        monitor = rtamt.StlDiscreteTimeOfflineSpecification()
        for v in variables:
            monitor.declare_var(v, "float")
        monitor.spec = text
        monitor.parse()
        monitors.append((monitor, variables))
    times = list(range(len(rows)))
    columns = {v: [r[v] for r in rows] for v in rows[0]}

    def run() -> int:
        for monitor, variables in monitors:
            monitor.evaluate({"time": times, **{v: columns[v] for v in variables}})
        return len(rows)

    return best(lambda: run)


def robust_rtamt_online(
    kind: str, n: int, rows: list[dict[str, float]]
) -> tuple[float, int] | None:
    try:
        import rtamt
    except ImportError:
        return None
    monitors = []
    for k in range(n):
        text, variables = robust_spec(kind, k, past=True)
        monitor = rtamt.StlDiscreteTimeSpecification()
        for v in variables:
            monitor.declare_var(v, "float")
        monitor.spec = text
        monitor.parse()
        monitors.append((monitor, variables))
    given = [[[(v, r[v]) for v in variables] for r in rows] for _, variables in monitors]

    def run() -> int:
        for (monitor, _), samples in zip(monitors, given, strict=True):
            for t, sample in enumerate(samples):
                monitor.update(t, sample)
        return len(rows)

    return best(lambda: run)


def robustness_rows(states: int) -> list[dict[str, Any]]:
    out = []
    full = robust_trace(states)
    for kind in ("R1", "R2", "R3"):
        for n in (1, 100):
            mine, count = robust_ours(kind, n, full[: max(states // n, 1_000)])
            row: dict[str, Any] = {"row": kind, "formulas": n, "ours": round(mine)}
            row["ours_states"] = count
            online, _ = robust_monitor(kind, n, full[: max(states // n, 1_000)])
            row["monitor"] = round(online)
            peer_states = max(200, min(states, int(PEER_BUDGET / (40e-6 * n))))
            got = robust_rtamt(kind, n, full[:peer_states])
            if got is not None:
                row["rtamt"], row["rtamt_states"] = round(got[0]), got[1]
                row["x_rtamt"] = round(mine / got[0], 2)
                row["x_monitor"] = round(online / got[0], 2)
            online_states = max(200, min(states, int(PEER_BUDGET / (100e-6 * n))))
            got = robust_rtamt_online(kind, n, full[:online_states])
            if got is not None:
                row["rtamt_online"], row["rtamt_online_states"] = round(got[0]), got[1]
                row["x_rtamt_online"] = round(mine / got[0], 2)
                row["x_monitor_online"] = round(online / got[0], 2)
            out.append(row)
    return out


def print_robustness(rows: list[dict[str, Any]]) -> None:
    print(
        "robustness: states/s (CPU, best of 3); dkreason's margin at every state (offline) and "
        "its monitor with robustness; rtamt's offline evaluator (the same formulas) and its "
        "online monitor (their past-time forms); x off: dkreason offline / rtamt offline; "
        "x mon: dkreason's monitor / rtamt offline; x mon on: dkreason's monitor / rtamt online"
    )
    print(
        f"{'row':<4}{'n':>4}{'offline':>12}{'monitor':>12}{'rtamt':>10}{'x off':>8}"
        f"{'x mon':>8}{'rtamt on':>10}{'x mon on':>10}  target"
    )
    for r in rows:
        ratios = [r.get(k, TARGET_RTAMT) for k in ("x_rtamt", "x_monitor", "x_monitor_online")]
        print(
            f"{r['row']:<4}{r['formulas']:>4}{r['ours']:>12,}{r['monitor']:>12,}"
            f"{r.get('rtamt', 0):>10,}{r.get('x_rtamt', '-'):>8}{r.get('x_monitor', '-'):>8}"
            f"{r.get('rtamt_online', 0):>10,}{r.get('x_monitor_online', '-'):>10}  "
            f"{'met' if min(ratios) >= TARGET_RTAMT else 'MISSED'}  "
            f"[{r['ours_states']:,} / {r.get('rtamt_states', '-')} / "
            f"{r.get('rtamt_online_states', '-')}]"
        )


def robust_memory(states: int) -> list[tuple[int, int, int]]:
    """Traced memory (bytes) at each quarter of an R3 monitor with robustness, and the most
    within that quarter (the states kept grow and shrink with each fold: the quarters' ends
    fall at different points of that cycle)."""
    rows = [{FeatureKey(v): x for v, x in row.items()} for row in robust_trace(20_000)]
    p = Progressor(robustness=True)
    p.add(robust_spec("R3", 0)[0])
    marks, out = {states * q // 4 for q in (1, 2, 3, 4)}, []
    tracemalloc.start()
    try:
        for t in range(states):
            p.step(t, dict(rows[t % len(rows)]))
            if t + 1 in marks:
                current, peak = tracemalloc.get_traced_memory()
                out.append((t + 1, current, peak))
                tracemalloc.reset_peak()
    finally:
        tracemalloc.stop()
    return out


def memory(states: int) -> list[tuple[int, int]]:
    """Traced memory (bytes) after 10%, 50% and 100% of a P3 run."""
    rows = trace("P3", 20_000)
    p = Progressor()
    p.add(spec("P3", 0).ours)
    marks, out = {states // 10, states // 2, states}, []
    tracemalloc.start()
    try:
        for t in range(states):
            p.step(t, rows[t % len(rows)] if t % len(rows) or t == 0 else {"P": False, "Q": True})
            if t + 1 in marks:
                out.append((t + 1, tracemalloc.get_traced_memory()[0]))
    finally:
        tracemalloc.stop()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--states", type=int, default=100_000)
    parser.add_argument("--memory-states", type=int, default=1_000_000)
    parser.add_argument("--robustness-states", type=int, default=20_000)
    parser.add_argument("--robustness-only", action="store_true")
    args = parser.parse_args()
    robust = robustness_rows(args.robustness_states)
    robust_mem = robust_memory(args.memory_states)
    if args.robustness_only:
        if args.json:
            print(json.dumps({"robustness": robust, "robustness_memory": robust_mem}, indent=1))
        else:
            print_robustness(robust)
            print_memory("R3 with robustness", robust_mem)
        return
    results = []
    for kind in ("P1", "P2", "P3", "P4", "P5"):
        full = trace(kind, args.states)
        for n in (1, 10, 100):
            mine, count = ours(kind, n, full[: max(args.states // n, 10_000)])
            row: dict[str, Any] = {
                "row": kind,
                "formulas": n,
                "ours": round(mine),
                "ours_states": count,
            }
            for name, runner, cost in (
                ("rtamt", with_rtamt, 100e-6),
                ("reelay", with_reelay, 1.5e-6),
            ):
                peer_states = max(200, min(len(full), int(PEER_BUDGET / (cost * n))))
                got = runner(kind, n, full[:peer_states])
                if got is not None:
                    row[name], row[f"{name}_states"] = round(got[0]), got[1]
                    row[f"x_{name}"] = round(mine / got[0], 2)
            results.append(row)
    mem = memory(args.memory_states)
    if args.json:
        print(
            json.dumps(
                {
                    "rows": results,
                    "robustness": robust,
                    "memory": mem,
                    "robustness_memory": robust_mem,
                },
                indent=1,
            )
        )
        return
    print("states/s (CPU, best of 3); ours/peer ratio; [states per run]")
    print(
        f"{'row':<4}{'n':>4}{'dkreason':>12}{'rtamt':>10}{'x rtamt':>9}{'reelay':>11}"
        f"{'x reelay':>10}  target"
    )
    for r in results:
        ok_rtamt = r.get("x_rtamt", TARGET_RTAMT) >= TARGET_RTAMT
        ok_reelay = r["row"] == "P5" or r.get("x_reelay", 1.0) >= 1.0
        verdict = "met" if ok_rtamt and ok_reelay else "MISSED"
        print(
            f"{r['row']:<4}{r['formulas']:>4}{r['ours']:>12,}{r.get('rtamt', 0):>10,}"
            f"{r.get('x_rtamt', '-'):>9}{r.get('reelay', 0):>11,}{r.get('x_reelay', '-'):>10}"
            f"  {verdict}  [{r['ours_states']:,} / {r.get('rtamt_states', '-')} / "
            f"{r.get('reelay_states', '-')}]"
        )
    print_robustness(robust)
    print_memory("P3", mem)
    print_memory("R3 with robustness", robust_mem)


def print_memory(what: str, marks: list[tuple[int, int]] | list[tuple[int, int, int]]) -> None:
    print(
        f"memory of {what} over a long run (states: traced bytes"
        + (", the most in the quarter" if len(marks[0]) > 2 else "")
        + "): "
        + ", ".join(f"{m[0]:,}: " + " / ".join(f"{b:,}" for b in m[1:]) for m in marks)
    )


if __name__ == "__main__":
    main()
