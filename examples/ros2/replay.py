"""Replay a ROS 2 recording as the live ROS 2 topics of its robots, in rmw_zenoh's wire format
(or zenoh-bridge-ros2dds' with --bridge), with /clock as `ros2 bag play --clock` publishes it.
No ROS installation is needed: this is what `make ros2-demo` monitors.

    python examples/ros2/replay.py examples/traffic/recording --listen tcp/127.0.0.1:7448 \\
        --speed 30 --delay 3
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from dkreason.errors import DkError
from dkreason.live.session import open_session
from dkreason.live.testing import replay


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("--listen", action="append", default=[], metavar="ENDPOINT")
    parser.add_argument("--connect", action="append", default=[], metavar="ENDPOINT")
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument(
        "--delay",
        type=float,
        default=0.0,
        help="seconds between announcing the publishers and the first message",
    )
    parser.add_argument(
        "--wait-for",
        action="append",
        default=[],
        metavar="TOPIC",
        help="start once TOPIC has a subscriber (repeatable)",
    )
    parser.add_argument(
        "--bridge", action="store_true", help="announce the topics as zenoh-bridge-ros2dds does"
    )
    parser.add_argument("--domain", type=int, default=0)
    args = parser.parse_args()
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:
        session = open_session(args.connect, args.listen)
        try:
            sent = replay(
                args.recording,
                session,
                speed=args.speed,
                domain=args.domain,
                bridged=args.bridge,
                wait_for=args.wait_for,
                delay=args.delay,
                stop=stop,
            )
        finally:
            session.close()
    except DkError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"replayed {sent} messages", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
