"""End-to-end messages per second, recording to verdicts, beside rosbags' own read rates.

An MCAP file of 1,000,000 CarMsg messages (three cars at 100 Hz each, platform 1's topics of
the bundled thesis scenario, made once under benchmarks/out/) is monitored for 10 formulas
(invariants and response formulas over the three cars' speeds, none violated) with the default
policy (a state on every change, 5 s maximum age), and for 1,000 such formulas.  In the same
run, the rates at which rosbags alone iterates over the same messages, and iterates and
deserialises them.  Figures are CPU time, best of ROUNDS runs.  The same messages split over
two recordings (cars 1–2 and car 3) are merged by record time as `--source a --source b` does.
Memory: Python's traced heap at each quarter of a replay (flat: it does not grow with the
recording).

Targets (issue 16): end to end >= 1.0 of iterate-and-deserialise and >= 0.6 of bare
iteration; 1,000 formulas >= 0.8 of 10; two recordings >= 0.95 of one; memory flat.

A fleet (issue 28): `forall c in Car: always (Speed[c] > 60 -> eventually[0, 30] Speed[c] <=
60)` over 1,000 cars on one topic (CAR_MESSAGES messages, every car at 10 Hz), judged per car
(an instance each), beside the same formula written out as one conjunction of 1,000 responses
(judged as one formula, as quantifiers were before).  Target: instances >= 0.8 of expanded.

    python -m benchmarks.bench_monitor [--json] [--messages N]
"""

from __future__ import annotations

import argparse
import gc
import json
import time
import tracemalloc
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from dkreason import KnowledgeManager
from dkreason.monitor import Monitor
from dkreason.progress import Verdict
from dkreason.stream.binding import Recording, Recordings
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.recording import write_recording
from dkreason.stream.sources import RosbagSource

ROUNDS = 3
REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "benchmarks" / "out"
CAR = "dkreason_msgs/msg/CarMsg"
FORMULAS = [
    *(f"always (Speed[car{n}] > 0)" for n in (1, 2, 3)),
    *(f"always (Speed[car{n}] > 60 -> eventually[0, 30] Speed[car{n}] <= 60)" for n in (1, 2, 3)),
    "always (Speed[car1] < 200 and Speed[car2] < 200 and Speed[car3] < 200)",
    "always not (always[0, 60] Speed[car2] > 60)",
    "always (Speed[car1] + Speed[car2] < 400)",
    "forall c in Car: always (Speed[c] >= 0)",
]


def recording(messages: int, cars: tuple[int, ...] = (1, 2, 3)) -> Path:
    path = OUT / f"cars-{messages}{'' if cars == (1, 2, 3) else '-' + ''.join(map(str, cars))}.mcap"
    if path.exists():
        return path
    OUT.mkdir(parents=True, exist_ok=True)

    per_car = messages // 3

    def rows() -> Iterator[tuple[str, str, int, dict[str, Any]]]:
        """All three cars at 100 Hz; car2 speeds for 10 s in every 20 s, and ends slow."""
        for i in range(per_car * 3):
            car, k = i % 3 + 1, i // 3
            speeding = car == 2 and k % 2000 < 1000 and k < per_car - 1000
            speed = 65.0 if speeding else 40.0 + (k % 1000) / 50
            if car in cars:
                yield (f"/platform1/topic{car + 2}", CAR, k * 10_000_000, {"id": car, "spd": speed})

    write_recording(path, "bare-mcap", {CAR: "int32 id\nfloat64 spd\n"}, rows())
    return path


def best(run: Callable[[], int]) -> float:
    rates: list[float] = []
    for _ in range(ROUNDS):
        gc.collect()
        start = time.process_time()
        n = run()
        rates.append(n / max(time.process_time() - start, 1e-9))
    return max(rates)


def raw_rate(path: Path, deserialise: bool = True) -> float:
    def run() -> int:
        source = RosbagSource(path)
        reader, n = source.reader, 0
        for connection, _, raw in reader.messages():
            if deserialise:
                reader.deserialize(raw, connection.msgtype)
            n += 1
        source.close()
        return n

    return best(run)


def many(n: int) -> list[str]:
    """n formulas over the three cars, none violated (car2 speeds 10 s in every 20)."""
    shapes = [
        "always (Speed[car{c}] > -{k})",
        "always (Speed[car{c}] < 200 + {k})",
        "always (Speed[car{c}] > 60 -> eventually[0, {w}] Speed[car{c}] <= 60)",
        "always not (always[0, {w}] Speed[car2] > 60)",
    ]
    return [shapes[i % 4].format(c=i % 3 + 1, k=i, w=30 + i) for i in range(n)]


def end_to_end(*paths: Path, formulas: list[str] = FORMULAS) -> tuple[float, list[Verdict]]:
    km = KnowledgeManager.from_config(REPO / "examples" / "single.toml")
    verdicts: list[Verdict] = []

    def run() -> int:
        monitor = Monitor(km.plan(formulas), km.request, StreamPolicy())
        source = Recordings([Recording(RosbagSource(p), None) for p in paths])
        n = source.count(None) or 0
        verdicts[:] = [e for e in monitor.run(source) if isinstance(e, Verdict)]
        return n

    return best(run), verdicts


CARS = 1000
CAR_MESSAGES = 20_000
FLEET = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 30] Speed[c] <= 60)"
FLEET_TTL = """@prefix : <http://example.org/fleet#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Car a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:Speed a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Car ] ) ] .
"""


def fleet() -> tuple[Path, Path]:
    """A config of CARS cars on one topic (`Speed(Car) = msg.spd for some Car = msg.id`) and a
    recording of CAR_MESSAGES messages: each car at 10 Hz, speeding one message in seven,
    slow again at its next."""
    folder = OUT / f"fleet-{CARS}"
    config, path = folder / "fleet.toml", folder / f"cars-{CAR_MESSAGES}.mcap"
    if path.exists():
        return config, path
    folder.mkdir(parents=True, exist_ok=True)
    cars = "".join(f":car{k} a owl:NamedIndividual, :Car .\n" for k in range(CARS))
    (folder / "fleet.ttl").write_text(FLEET_TTL + cars)
    (folder / "fleet.sslt").write_text(
        "topic cars:CarMsg contains Speed(Car) = msg.spd for some Car = msg.id\n"
    )
    config.write_text('[platforms.fleet]\nontology = "fleet.ttl"\nspecs = "fleet.sslt"\n')
    last = CAR_MESSAGES - CARS  # the last round: no window left open at the end
    rows = (
        ("/fleet/cars", CAR, i * 100_000, {"id": i % CARS, "spd": 65.0 if speeding else 50.0})
        for i in range(CAR_MESSAGES)
        for speeding in [i % 7 == 0 and i < last]
    )
    write_recording(path, "bare-mcap", {CAR: "int32 id\nfloat64 spd\n"}, rows)
    return config, path


def per_object() -> tuple[float, float]:
    """msgs/s of the fleet formula judged per car, and written out as one conjunction."""
    config, path = fleet()
    km = KnowledgeManager.from_config(config)
    expanded = " and ".join(
        f"always (Speed[car{k}] > 60 -> eventually[0, 30] Speed[car{k}] <= 60)" for k in range(CARS)
    )

    def rate(formula: str) -> float:
        plan = km.plan(formula)

        def run() -> int:
            source = Recordings([Recording(RosbagSource(path), None)])
            n = source.count(None) or 0
            verdicts = [e for e in Monitor(plan, km.request, StreamPolicy()).run(source)]
            assert all(isinstance(v, Verdict) and v.verdict for v in verdicts), verdicts[:1]
            return n

        return best(run)

    return rate(FLEET), rate(expanded)


def heap_by_quarter(path: Path) -> list[int]:
    """Traced heap bytes after each quarter of the messages (10 formulas)."""
    km = KnowledgeManager.from_config(REPO / "examples" / "single.toml")
    source = Recordings([Recording(RosbagSource(path), None)])
    total = source.count(None) or 1
    points: list[tuple[int, int]] = []
    tracemalloc.start()
    for _ in Monitor(km.plan(FORMULAS), km.request, StreamPolicy()).run(
        source, lambda n: points.append((n, tracemalloc.get_traced_memory()[0]))
    ):
        pass
    tracemalloc.stop()
    return [
        max((p for p in points if p[0] <= total * q // 4), default=(0, 0))[1] for q in (1, 2, 3, 4)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--messages", type=int, default=1_000_000)
    args = parser.parse_args()
    path = recording(args.messages)
    bare, raw = raw_rate(path, deserialise=False), raw_rate(path)
    e2e, verdicts = end_to_end(path)
    assert all(v.verdict is True for v in verdicts), "a benchmark formula failed"
    split, merged_verdicts = end_to_end(
        recording(args.messages, (1, 2)), recording(args.messages, (3,))
    )
    assert merged_verdicts == verdicts, "two recordings gave other verdicts than one"
    thousand, judged = end_to_end(path, formulas=many(1000))
    assert all(v.verdict is True for v in judged), "a benchmark formula failed"
    heap = heap_by_quarter(path)
    instances, expanded = per_object()
    result = {
        "messages": args.messages,
        "formulas": len(FORMULAS),
        "bare_read": round(bare),
        "raw_read": round(raw),
        "end_to_end": round(e2e),
        "ratio": round(e2e / raw, 3),
        "ratio_bare": round(e2e / bare, 3),
        "two_recordings": round(split),
        "two_vs_one": round(split / e2e, 3),
        "thousand": round(thousand),
        "thousand_vs_ten": round(thousand / e2e, 3),
        "heap_by_quarter": heap,
        "fleet_instances": round(instances),
        "fleet_expanded": round(expanded),
        "instances_vs_expanded": round(instances / expanded, 3),
        "targets_met": instances >= 0.8 * expanded
        and e2e >= raw
        and e2e >= 0.6 * bare
        and split >= 0.95 * e2e
        and thousand >= 0.8 * e2e
        and heap[-1] <= 1.1 * heap[0] + 1e6,
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"{args.messages:,} messages (CPU, best of {ROUNDS})")
    print(f"  rosbags, iterate only:            {bare:>9,.0f} msgs/s")
    print(f"  rosbags, iterate + deserialise:   {raw:>9,.0f} msgs/s")
    print(
        f"  dkreason end to end, 10 formulas: {e2e:>9,.0f} msgs/s  ({e2e / raw:.2f} of "
        f"iterate + deserialise, target 1.0; {e2e / bare:.2f} of iterate, target 0.6)"
    )
    print(
        f"  the same in two recordings:       {split:>9,.0f} msgs/s  ({split / e2e:.2f} of one, "
        f"target 0.95)"
    )
    print(
        f"  1,000 formulas:                   {thousand:>9,.0f} msgs/s  ({thousand / e2e:.2f} "
        f"of 10, target 0.8)"
    )
    print(f"  heap after each quarter (bytes):  {', '.join(f'{b:,}' for b in heap)}")
    print(
        f"  {CARS:,} cars, per object:          {instances:>9,.0f} msgs/s  "
        f"({instances / expanded:.2f} of the formula expanded, {expanded:,.0f} msgs/s; "
        "target 0.8)"
    )
    print(f"  targets {'met' if result['targets_met'] else 'MISSED (see above)'}")


if __name__ == "__main__":
    main()
