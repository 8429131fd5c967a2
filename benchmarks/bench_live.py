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
import queue
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
# the violation to find, and one that stays open so the run lasts until every sample is taken
FORMULAS = [f"forall s in Sensor: always (Reading[s] < {LIMIT})", "always (Reading[p1s1] >= 0)"]


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
        return (
            f'<cowl:bridgeRule cowl:br-type="{kind}"><cowl:sourceConcept rdf:resource='
            f'"http://example.org/bench/p1#{a}"/><cowl:targetConcept rdf:resource='
            f'"http://example.org/bench/p{n}#{b}"/></cowl:bridgeRule>'
        )

    rules = [rule("equiv", "Reading", "Reading"), rule("equiv", "Sensor", "Sensor")]
    rules += [rule("same", f"p1s{k}", f"p{n}s{k}") for k in range(1, 11)]
    return (
        '<cowl:mapping xmlns:cowl="http://www.itc.it/cowl#" '
        'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
        + "".join(rules)
        + "</cowl:mapping>\n"
    )


def write(folder: Path) -> None:
    monitor = ['local = "p1"'] + [f"[platforms.p{n}]" for n in range(1, PLATFORMS + 1)]
    for n in range(1, PLATFORMS + 1):
        (folder / f"p{n}.ttl").write_text(_turtle(n))
        (folder / f"p{n}.sslt").write_text(
            "".join(
                f"topic t{k}:Reading contains Reading(p{n}s{k}) = msg.value for p{n}s{k} = msg.id\n"
                for k in range(1, TOPICS + 1)
            )
        )
        (folder / f"p{n}.toml").write_text(
            f'[platforms.p{n}]\nontology = "p{n}.ttl"\nspecs = "p{n}.sslt"\n'
        )
        if n > 1:
            (folder / f"p1-p{n}.cowl.xml").write_text(_mapping(n))
            monitor.append(
                f'[[mappings]]\nsource = "p1"\ntarget = "p{n}"\nfile = "p1-p{n}.cowl.xml"'
            )
    (folder / "monitor.toml").write_text("\n".join(monitor) + "\n")


def publisher(
    folder: str,
    n: int,
    endpoint: str,
    start: float,
    seconds: float,
    hz: float,
    done: Any,
    finished: Any,
) -> None:
    """One platform: 10 topics at `hz` from `start` for `seconds`; platform 3 then sends the
    violating reading.  Puts (published, wall ns of the bad reading) on `done`, and keeps its
    session (and what is still queued in it) until `finished`."""
    from dkreason import KnowledgeManager
    from dkreason.live.serve import PlatformNode
    from dkreason.live.session import open_session

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
        if hz:
            tick += 1 / hz
            time.sleep(max(0.0, tick - time.time()))
        else:  # a flood: as fast as it can
            tick = time.time()
    if n == PLATFORMS:
        bad_at = time.time_ns()
        node.publish("t1", {"id": 1, "value": float(BAD)}, valid=bad_at)
        published += 1
    done.put((published, bad_at))
    finished.wait(120)  # the monitor reads the last samples before the token goes
    node.close()
    session.close()


class Fleet:
    """Publisher processes started together (spawned: no state shared), and the monitor
    stopped once it has taken every sample they published (or a minute after they are done):
    a flood's backlog is drained, not cut off when its publishers stop."""

    def __init__(
        self, target: Any, args: list[tuple[Any, ...]], seconds: float, hz: float, monitor: Any
    ) -> None:
        ctx = mp.get_context("spawn")
        self.done, self.finished = ctx.Queue(), ctx.Event()
        start = time.time() + 4
        self.procs = [
            ctx.Process(target=target, args=(*a, start, seconds, hz, self.done, self.finished))
            for a in args
        ]
        for p in self.procs:
            p.start()
        self.results: list[tuple[int, int | None]] = []
        self.watcher = threading.Thread(target=self._watch, args=(monitor,), daemon=True)
        self.watcher.start()

    def _watch(self, monitor: Any) -> None:
        for _ in self.procs:
            try:
                self.results.append(self.done.get(timeout=300))
            except queue.Empty:
                break
        published = sum(r[0] for r in self.results)
        end = time.monotonic() + 60
        while monitor.received < published and time.monotonic() < end:
            time.sleep(0.01)
        monitor.stop.set()

    def stop(self) -> list[tuple[int, int | None]]:
        self.watcher.join(timeout=400)
        self.finished.set()
        for p in self.procs:
            p.join(timeout=15)
        return self.results


class Meter:
    """What a monitor's stream processor did, timed: publish → state progressed per state (the
    state's time is the sample's publish stamp), and when it took its first and last sample
    (the rate it sustained, whatever the backlog)."""

    def __init__(self) -> None:
        self.latencies: list[int] = []
        self.first = self.last = 0.0
        self.processor: Any = None

    def attach(self, processor: Any) -> None:
        self.processor = processor
        step, put = processor.on_state, processor.put

        def timed(t: int, values: dict[Any, Any], *rest: Any) -> None:
            step(t, values, *rest)
            self.latencies.append(time.time_ns() - t)

        def taken(*args: Any) -> None:
            self.last = time.monotonic()
            self.first = self.first or self.last
            put(*args)

        processor.on_state, processor.put = timed, taken

    def rate(self, received: int) -> int:
        """Samples a second from the first sample taken to the last."""
        span = self.last - self.first
        return round(received / span) if span > 0 else 0


def run(seconds: float, hz: float) -> dict[str, Any]:
    from dkreason import KnowledgeManager
    from dkreason.live.monitor import LiveMonitor
    from dkreason.live.session import open_session
    from dkreason.progress import Verdict
    from dkreason.stream.policy import StreamPolicy

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write(folder)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        endpoint = f"tcp/127.0.0.1:{port}"
        session = open_session([], [endpoint])
        policy = StreamPolicy(max_age=Fraction(1))
        km = KnowledgeManager.from_config(folder / "monitor.toml", live=True)
        monitor = LiveMonitor(km, FORMULAS, policy, session, wait=30)
        fleet = Fleet(
            publisher,
            [(str(folder), n, endpoint) for n in range(1, PLATFORMS + 1)],
            seconds,
            hz,
            monitor,
        )
        meter = Meter()
        verdict_at = None
        try:
            for event in monitor.run(duration=seconds + 60):
                if meter.processor is None and monitor.processor is not None:
                    meter.attach(monitor.processor)
                if isinstance(event, Verdict) and event.verdict is False:
                    verdict_at = time.time_ns()
        finally:
            results = fleet.stop()
            session.close()
    return {
        "platforms": PLATFORMS,
        "topics_per_platform": TOPICS,
        "hz": hz,
        "seconds": seconds,
        **figures(results, monitor.received, meter, verdict_at),
    }


def figures(
    results: list[tuple[int, int | None]], received: int, meter: Meter, verdict_at: int | None
) -> dict[str, Any]:
    """Samples published (each publisher's count, and the wall ns of the bad reading) and
    taken, the rate, publish → state latencies, and the bad reading's publish → verdict."""
    published = sum(r[0] for r in results)
    bad_at = next((r[1] for r in results if r[1] is not None), None)
    ms = sorted(x / 1e6 for x in meter.latencies if x > 0)
    return {
        "published": published,
        "received": received,
        "lost": published - received,
        "samples_per_s": meter.rate(received),
        "states": len(ms),
        "p50_ms": round(statistics.median(ms), 2),
        "p99_ms": round(ms[int(0.99 * (len(ms) - 1))], 2),
        "max_ms": round(ms[-1], 2),
        "violation_to_verdict_ms": None
        if verdict_at is None or bad_at is None
        else round((verdict_at - bad_at) / 1e6, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument(
        "--hz",
        type=float,
        default=100.0,
        help="rate of each topic (0: as fast as each publisher can)",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    r = run(args.seconds, args.hz)
    if args.json:
        print(json.dumps(r))
        return
    print(
        f"{r['platforms']} platforms x {r['topics_per_platform']} topics at {r['hz']:g} Hz, "
        f"{r['seconds']:g} s over loopback Zenoh"
    )
    print(
        f"  samples: {r['published']} published, {r['received']} received, {r['lost']} lost "
        f"({'target: none lost ✓' if r['lost'] == 0 else 'target: none lost ✗'})"
    )
    print(f"  sustained: {r['samples_per_s']} samples/s received")
    print(
        f"  publish → state progressed: p50 {r['p50_ms']} ms, p99 {r['p99_ms']} ms, "
        f"max {r['max_ms']} ms over {r['states']} states "
        f"(target p99 < 20 ms {'✓' if r['p99_ms'] < 20 else '✗'})"
    )
    print(f"  publish → violation verdict: {r['violation_to_verdict_ms']} ms")


if __name__ == "__main__":
    main()
