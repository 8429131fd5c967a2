"""Publish-to-verdict latency and sustained rate of a live federation over loopback Zenoh.

Three platform nodes (separate processes, `PlatformNode` through the Python API) each publish
10 topics at 100 Hz — one sensor reading per topic, stamped with the wall clock when published.
(`--hz` raises the rate to find where the monitor saturates.)
Platform 1's ten sensors are the same objects as platforms 2's and 3's (bridge rules), so each
of the monitor's ten features merges three topics.  The monitor (this process, `LiveMonitor`)
progresses `forall s in Sensor: always (Reading[s] < 1000)`; at the end platform 3 publishes a
reading of 5000, and the monitor must report the violation.

Figures: per sample, publish → its state progressed by the monitor (the instant a verdict
could be issued), p50 and p99; the final violation's publish → verdict; samples received per
second against published (none may be lost).  Targets: p99 under 20 ms, no sample lost.

    python -m benchmarks.bench_live [--seconds 10] [--hz 100] [--json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import socket
import statistics
import tempfile
import threading
import time
from fractions import Fraction
from pathlib import Path
from typing import Any

TOPICS, PLATFORMS = 10, 3
LIMIT, BAD = 1000, 5000


def _turtle(n: int) -> str:
    objects = "\n".join(f":p{n}s{k} a owl:NamedIndividual, :Sensor ." for k in range(1, 11))
    return f"""@prefix : <http://example.org/bench/p{n}#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Relation a owl:Class .
:UnaryRelation rdfs:subClassOf :Relation .
:arg1 a owl:ObjectProperty .
:Sensor a owl:Class .
:Reading rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :UnaryRelation
    [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Sensor ] ) ] .
{objects}
"""


def _mapping(n: int) -> str:
    def rule(kind: str, a: str, b: str) -> str:
        return (f'<cowl:bridgeRule cowl:br-type="{kind}"><cowl:sourceConcept rdf:resource='
                f'"http://example.org/bench/p1#{a}"/><cowl:targetConcept rdf:resource='
                f'"http://example.org/bench/p{n}#{b}"/></cowl:bridgeRule>')
    rules = [rule("equiv", "Reading", "Reading"), rule("equiv", "Sensor", "Sensor")]
    rules += [rule("same", f"p1s{k}", f"p{n}s{k}") for k in range(1, 11)]
    return ('<cowl:mapping xmlns:cowl="http://www.itc.it/cowl#" '
            'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
            + "".join(rules) + "</cowl:mapping>\n")


def write(folder: Path) -> None:
    monitor = ['local = "p1"'] + [f"[platforms.p{n}]" for n in range(1, PLATFORMS + 1)]
    for n in range(1, PLATFORMS + 1):
        (folder / f"p{n}.ttl").write_text(_turtle(n))
        (folder / f"p{n}.sslt").write_text("".join(
            f"topic t{k}:Reading contains Reading(p{n}s{k}) = msg.value for p{n}s{k} = msg.id\n"
            for k in range(1, TOPICS + 1)))
        (folder / f"p{n}.toml").write_text(f'[platforms.p{n}]\nontology = "p{n}.ttl"\n'
                                           f'specs = "p{n}.sslt"\n')
        if n > 1:
            (folder / f"p1-p{n}.cowl.xml").write_text(_mapping(n))
            monitor.append(f'[[mappings]]\nsource = "p1"\ntarget = "p{n}"\n'
                           f'file = "p1-p{n}.cowl.xml"')
    (folder / "monitor.toml").write_text("\n".join(monitor) + "\n")


def publisher(folder: str, n: int, endpoint: str, start: float, seconds: float, hz: float,
              done: Any) -> None:
    """One platform: 10 topics at `hz` from `start` for `seconds`; platform 3 then sends the
    violating reading.  Puts (published, wall ns of the bad reading) on `done`."""
    from dkreason import KnowledgeManager
    from dkreason.live.serve import PlatformNode
    from dkreason.live.wire import open_session

    km = KnowledgeManager.from_config(Path(folder) / f"p{n}.toml")
    session = open_session([endpoint], [])
    node = PlatformNode(km, session, heartbeat=0.01)
    clock = threading.Thread(target=node.serve, daemon=True)
    clock.start()
    published, tick, bad_at = 0, start, None
    time.sleep(max(0.0, start - time.time()))
    while tick < start + seconds:
        for k in range(1, TOPICS + 1):
            node.publish(f"t{k}", {"id": k, "value": float(k)})
            published += 1
        tick += 1 / hz
        time.sleep(max(0.0, tick - time.time()))
    if n == PLATFORMS:
        bad_at = time.time_ns()
        node.publish("t1", {"id": 1, "value": float(BAD)}, valid=bad_at)
        published += 1
    time.sleep(1.0)  # the monitor reads the last samples before the token goes
    done.put((published, bad_at))
    node.close()
    session.close()


def run(seconds: float, hz: float) -> dict[str, Any]:
    from dkreason.live.monitor import LiveMonitor
    from dkreason.live.wire import open_session
    from dkreason.model import FeatureKey
    from dkreason.progress import Verdict
    from dkreason.stream.processor import StreamPolicy

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write(folder)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        endpoint = f"tcp/127.0.0.1:{port}"
        session = open_session([], [endpoint])
        policy = StreamPolicy(max_age=Fraction(1))
        monitor = LiveMonitor(folder / "monitor.toml",
                              [f"forall s in Sensor: always (Reading[s] < {LIMIT})"], policy,
                              session, wait=30)
        ctx = mp.get_context("spawn")
        done = ctx.Queue()
        start = time.time() + 4
        procs = [ctx.Process(target=publisher, args=(str(folder), n, endpoint, start, seconds,
                                                     hz, done))
                 for n in range(1, PLATFORMS + 1)]
        for p in procs:
            p.start()
        latencies: list[int] = []
        verdict_at = None
        try:
            for event in monitor.run(duration=seconds + 30):
                if not latencies and hasattr(monitor, "processor"):
                    step = monitor.processor.on_state

                    def timed(t: int, values: dict[FeatureKey, Any], *rest: Any,
                              step: Any = step) -> None:
                        step(t, values, *rest)
                        latencies.append(time.time_ns() - t)
                    monitor.processor.on_state = timed
                    latencies.append(0)
                if isinstance(event, Verdict) and event.verdict is False:
                    verdict_at = time.time_ns()
        finally:
            for p in procs:
                p.join(timeout=10)
            session.close()
        results = [done.get(timeout=5) for _ in procs]
    published = sum(r[0] for r in results)
    bad_at = next(r[1] for r in results if r[1] is not None)
    ms = sorted(x / 1e6 for x in latencies[1:] if x > 0)
    return {"platforms": PLATFORMS, "topics_per_platform": TOPICS, "hz": hz,
            "seconds": seconds, "published": published, "received": monitor.received,
            "lost": published - monitor.received,
            "samples_per_s": round(monitor.received / seconds),
            "states": len(ms),
            "p50_ms": round(statistics.median(ms), 2),
            "p99_ms": round(ms[int(0.99 * (len(ms) - 1))], 2),
            "max_ms": round(ms[-1], 2),
            "violation_to_verdict_ms": None if verdict_at is None else
            round((verdict_at - bad_at) / 1e6, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--hz", type=float, default=100.0, help="rate of each topic")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    r = run(args.seconds, args.hz)
    if args.json:
        print(json.dumps(r))
        return
    print(f"{r['platforms']} platforms x {r['topics_per_platform']} topics at {r['hz']:g} Hz, "
          f"{r['seconds']:g} s over loopback Zenoh")
    print(f"  samples: {r['published']} published, {r['received']} received, {r['lost']} lost "
          f"({'target: none lost ✓' if r['lost'] == 0 else 'target: none lost ✗'})")
    print(f"  sustained: {r['samples_per_s']} samples/s received")
    print(f"  publish → state progressed: p50 {r['p50_ms']} ms, p99 {r['p99_ms']} ms, "
          f"max {r['max_ms']} ms over {r['states']} states "
          f"(target p99 < 20 ms {'✓' if r['p99_ms'] < 20 else '✗'})")
    print(f"  publish → violation verdict: {r['violation_to_verdict_ms']} ms")


if __name__ == "__main__":
    main()
