"""A live fleet growing: how soon the monitor subscribes to a platform node that joins.

Twenty platform nodes (separate processes, `PlatformNode` through the Python API) join a
live monitor on loopback Zenoh one after another, every `--every` seconds.  All share one
vocabulary (the same IRIs: no mapping files, issue 15), each with its own sensor and topic,
publishing at 20 Hz.  The monitor progresses `forall s in Sensor: always (Reading[s] < 1000)`.
Figure per join: wall time from the node's arrival (its liveliness token declared) to the
monitor's subscription to its topic, with how many platforms were present.  Target (issue 16):
within 200 ms with 20 present.

    python -m benchmarks.bench_join [--nodes 20] [--every 0.5] [--json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import socket
import statistics
import sys
import tempfile
import threading
import time
from fractions import Fraction
from pathlib import Path
from typing import Any

from dkreason.workloads import fleet as write


def node(folder: str, n: int, endpoint: str, until: float, arrived: Any) -> None:
    """Platform n: serve, say when its token is out, publish at 20 Hz until `until`."""
    from dkreason import KnowledgeManager
    from dkreason.live.serve import PlatformNode
    from dkreason.live.session import open_session

    km = KnowledgeManager.from_config(Path(folder) / f"p{n}.toml")
    session = open_session([endpoint], [])
    platform = PlatformNode(km, session, heartbeat=0.01)
    arrived.put((f"p{n}", time.time()))
    threading.Thread(target=platform.serve, daemon=True).start()
    while time.time() < until:
        platform.publish(f"t{n}", {"id": n, "value": 1.0})
        time.sleep(0.05)
    platform.close()
    session.close()


def run(nodes: int, every: float) -> dict[str, Any]:
    from dkreason import KnowledgeManager
    from dkreason.live.change import Change
    from dkreason.live.monitor import LiveMonitor
    from dkreason.live.session import open_session
    from dkreason.stream.policy import StreamPolicy

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write(folder, nodes)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        endpoint = f"tcp/127.0.0.1:{port}"
        session = open_session([], [endpoint])
        monitor = LiveMonitor(
            KnowledgeManager.from_config(folder / "monitor.toml", live=True),
            ["forall s in Sensor: always (Reading[s] < 1000)"],
            StreamPolicy(max_age=Fraction(2)),
            session,
            wait=30,
        )
        ctx = mp.get_context("spawn")
        arrived = ctx.Queue()
        until = time.time() + 6 + nodes * every
        procs: list[Any] = []

        def launch() -> None:
            for n in range(1, nodes + 1):
                procs.append(ctx.Process(target=node, args=(str(tmp), n, endpoint, until, arrived)))
                procs[-1].start()
                time.sleep(every)

        threading.Thread(target=launch, daemon=True).start()
        subscribed: dict[str, float] = {}
        try:
            for event in monitor.run(duration=nodes * every + 8):
                if isinstance(event, Change) and event.event == "subscribed":
                    subscribed.setdefault(event.platform, time.time())
                if len(subscribed) == nodes:
                    break
        finally:
            monitor.close()
            for p in procs:
                p.join(timeout=15)
            session.close()
        arrivals = dict(arrived.get(timeout=5) for _ in procs)
    joins = sorted((arrivals[p], subscribed[p]) for p in subscribed if p in arrivals)
    ms = [(sub - arr) * 1e3 for arr, sub in joins]
    return {
        "nodes": nodes,
        "subscribed": len(subscribed),
        "every_s": every,
        "join_to_subscription_ms": [round(x, 1) for x in ms],
        "p50_ms": round(statistics.median(ms), 1) if ms else None,
        "max_ms": round(max(ms), 1) if ms else None,
        "last_ms": round(ms[-1], 1) if ms else None,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--nodes", type=int, default=20)
    parser.add_argument("--every", type=float, default=0.5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    result = run(args.nodes, args.every)
    if args.json:
        print(json.dumps(result))
        return 0
    print(
        f"{result['subscribed']} of {args.nodes} nodes subscribed, one joining every {args.every} s"
    )
    print(
        f"  arrival → subscription: p50 {result['p50_ms']} ms, max {result['max_ms']} ms; "
        f"the last (with {args.nodes - 1} present) {result['last_ms']} ms "
        f"(target: within 200 ms with 20 present)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
