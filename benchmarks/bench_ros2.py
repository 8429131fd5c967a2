"""Live ROS 2 monitoring (CDR over rmw_zenoh's wire format) beside dkreason's own JSON wire.

The same fleet as bench_live: three platforms of ten sensors each, platform 1's sensors the
same objects as the others' (bridge rules), so each of ten features merges three topics, and
`forall s in Sensor: always (Reading[s] < 1000)` is progressed.

- ROS 2 side: three publisher processes, each a ROS 2 node (`/p1` … `/p3`) publishing ten
  `sensor_msgs/msg/Temperature` topics in rmw_zenoh's format (CDR, attachment, liveliness
  tokens), stamped with the wall clock; the monitor is `Ros2Monitor` (`monitor --ros2`), which
  discovers, binds by name, reads the temperature and the stamp from the CDR bytes.  With no
  per-topic clock on ROS 2, states are made as the wall clock passes less the policy's delay
  (`--delay`, default 5 ms), which the latency includes.
- JSON side: bench_live's `dkreason serve` nodes and `LiveMonitor` (`monitor --live`).

Each side runs twice: paced (`--hz` per topic, default 100) for publish → state latency, and a
flood (every publisher as fast as it can for `--flood` s) for the rate the monitor sustains.
Figures side by side, with the CDR/JSON ratio.  Target: CDR no slower than JSON.

    python -m benchmarks.bench_ros2 [--seconds 10] [--hz 100] [--flood 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import socket
import tempfile
import time
from fractions import Fraction
from pathlib import Path
from typing import Any

from . import bench_live

TOPICS, PLATFORMS = bench_live.TOPICS, bench_live.PLATFORMS
TYPE = "sensor_msgs/msg/Temperature"


def write(folder: Path) -> None:
    """bench_live's platforms, plus ROS 2 specs (a topic per sensor) and a config that holds
    every platform's knowledge (the ROS 2 monitor asks no node for it)."""
    bench_live.write(folder)
    config = ['local = "p1"']
    for n in range(1, PLATFORMS + 1):
        (folder / f"p{n}-ros2.sslt").write_text(
            "".join(
                f"topic /p{n}/t{k}:{TYPE} contains Reading(p{n}s{k}) = msg.temperature\n"
                for k in range(1, TOPICS + 1)
            )
        )
        config.append(f'[platforms.p{n}]\nontology = "p{n}.ttl"\nspecs = "p{n}-ros2.sslt"')
        if n > 1:
            config.append(
                f'[[mappings]]\nsource = "p1"\ntarget = "p{n}"\nfile = "p1-p{n}.cowl.xml"'
            )
    (folder / "ros2.toml").write_text("\n".join(config) + "\n")


def ros2_publisher(
    n: int, endpoint: str, start: float, seconds: float, hz: float, done: Any, finished: Any
) -> None:
    """Platform n as a ROS 2 node: ten topics at `hz` from `start` for `seconds` (as fast as
    it can with hz 0); platform 3 then publishes the violating reading."""
    import struct

    from dkreason.live.ros2node import Ros2Node
    from dkreason.live.session import open_session

    session = open_session([endpoint], [])
    node = Ros2Node(session, "sensors", f"/p{n}")
    pubs = [node.publisher(f"/p{n}/t{k}", TYPE) for k in range(1, TOPICS + 1)]

    def message(value: float) -> bytes:  # Temperature: header, temperature, variance
        t = time.time_ns()
        return (
            b"\x00\x01\x00\x00"
            + struct.pack("<iII", t // 10**9, t % 10**9, 1)
            + b"\x00\x00\x00\x00"
            + struct.pack("<dd", value, 0.0)
        )

    time.sleep(max(0.0, start - time.time()))
    published, tick = 0, start
    while tick < start + seconds:
        for k, pub in enumerate(pubs, 1):
            pub.put(message(float(k)))
            published += 1
        if hz:
            tick += 1 / hz
            time.sleep(max(0.0, tick - time.time()))
        else:
            tick = time.time()
    bad_at = None
    if n == PLATFORMS:
        bad_at = time.time_ns()
        pubs[0].put(message(float(bench_live.BAD)))
        published += 1
    done.put((published, bad_at))
    finished.wait(120)
    node.close()
    session.close()


def run_ros2(folder: Path, seconds: float, hz: float, delay: Fraction) -> dict[str, Any]:
    from dkreason import KnowledgeManager
    from dkreason.live.ros2 import Ros2Monitor
    from dkreason.live.session import open_session
    from dkreason.progress import Verdict
    from dkreason.stream.policy import StreamPolicy
    from dkreason.stream.processor import Violation
    from dkreason.stream.typestore import load_typestore

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{s.getsockname()[1]}"
    session = open_session([], [endpoint])
    monitor = Ros2Monitor(
        KnowledgeManager.from_config(folder / "ros2.toml"),
        list(bench_live.FORMULAS),
        StreamPolicy(max_age=Fraction(1), delay_before_approximation=delay),
        session,
        store=load_typestore({}, False, "ros2_jazzy"),
    )
    meter = bench_live.Meter()
    meter.attach(monitor.processor)
    fleet = bench_live.Fleet(
        ros2_publisher, [(n, endpoint) for n in range(1, PLATFORMS + 1)], seconds, hz, monitor
    )
    verdict_at, late = None, 0
    try:
        for event in monitor.run(duration=seconds + 60):
            if isinstance(event, Verdict) and event.verdict is False:
                verdict_at = time.time_ns()
            if isinstance(event, Violation):
                late += 1
    finally:
        results = fleet.stop()
        session.close()
    return {
        "hz": hz,
        "seconds": seconds,
        **bench_live.figures(results, monitor.received, meter, verdict_at),
        "late_samples": late,
        "delay_ms": float(delay * 1000),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--hz", type=float, default=100.0, help="paced rate of each topic")
    parser.add_argument("--flood", type=float, default=3.0, help="seconds of the flood run")
    parser.add_argument(
        "--delay",
        type=float,
        default=0.005,
        help="ROS 2 side: seconds a state waits for its samples",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    delay = Fraction(args.delay).limit_denominator(10**9)
    rows: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write(folder)
        for mode, seconds, hz in (("paced", args.seconds, args.hz), ("flood", args.flood, 0)):
            rows[f"ros2 cdr {mode}"] = run_ros2(folder, seconds, hz, delay)
            rows[f"serve json {mode}"] = bench_live.run(seconds, hz)
    if args.json:
        print(json.dumps(rows))
        return
    print(
        f"{PLATFORMS} platforms x {TOPICS} topics over loopback Zenoh; paced: {args.hz:g} Hz "
        f"a topic for {args.seconds:g} s; flood: as fast as each publisher can for "
        f"{args.flood:g} s"
    )
    cols = (
        "published",
        "received",
        "lost",
        "samples_per_s",
        "p50_ms",
        "p99_ms",
        "violation_to_verdict_ms",
    )
    print(
        f"{'':<18}"
        + "".join(
            f"{c:>14}"
            for c in (
                "published",
                "received",
                "lost",
                "samples/s",
                "p50 ms",
                "p99 ms",
                "violation ms",
            )
        )
    )
    for name, r in rows.items():
        print(f"{name:<18}" + "".join(f"{r[c]!s:>14}" for c in cols))
    for mode in ("paced", "flood"):
        cdr, js = rows[f"ros2 cdr {mode}"], rows[f"serve json {mode}"]
        print(
            f"{mode}: CDR/JSON samples/s {cdr['samples_per_s'] / js['samples_per_s']:.2f}, "
            f"p99 {cdr['p99_ms']} vs {js['p99_ms']} ms; ROS 2 late samples "
            f"{cdr['late_samples']} (delay {cdr['delay_ms']:g} ms)  "
            f"(target: CDR no slower than JSON)"
        )


if __name__ == "__main__":
    main()
