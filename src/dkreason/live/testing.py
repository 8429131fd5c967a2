"""Simulators for tests, examples and benchmarks: a recording replayed as the live ROS 2
topics of its robots (rmw_zenoh's wire format, or the bridge's), so the ROS 2 monitor is
exercised without a ROS installation.  Production code never imports this module."""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

from ..errors import DkError
from ..stream.sources import RosbagSource
from ..stream.units import NS
from .rmw import CLOCK, CLOCK_TYPE
from .ros2node import Ros2Node, Ros2Publisher


def cdr_clock(t: int) -> bytes:
    """A rosgraph_msgs/msg/Clock at `t` ns."""
    sec, nanosec = divmod(t, NS)
    return b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nanosec)


def replay(
    path: Path,
    session: Any,
    *,
    speed: float = 1.0,
    domain: int = 0,
    bridged: bool = False,
    clock: bool = True,
    wait_for: Collection[str] = (),
    delay: float = 0.0,
    timeout: float = 30.0,
    stop: threading.Event | None = None,
    heartbeat: float = 0.02,
) -> int:
    """Publish a ROS 2 recording's messages as live topics, as its robots would: a node per
    robot (the first part of a topic's name: `/platform2/carstopic1` is robot platform2's),
    payloads as recorded, paced at `speed`.  With `clock`, a player node publishes `/clock`
    (sim time) at each record time before its messages, and every `heartbeat` wall seconds
    between them, as `ros2 bag play --clock` does.  The first message goes out `delay` s after
    the publishers are announced and once each topic of `wait_for` has a subscriber (at most
    `timeout` s), so a monitor misses none.  Returns the number of messages published."""
    source = RosbagSource(path)
    stop = stop or threading.Event()
    nodes: dict[str, Ros2Node] = {}
    pubs: dict[str, Ros2Publisher] = {}
    player = Ros2Node(session, "rosbag2_player", "/", domain, bridged)
    ticks = player.publisher(CLOCK, CLOCK_TYPE) if clock else None
    for c in source.connections:  # its ROS channels (an MCAP may hold JSON ones too)
        robot = c.topic.strip("/").split("/")[0] if c.topic.count("/") > 1 else ""
        node = nodes.get(robot)
        if node is None:
            node = nodes[robot] = Ros2Node(session, "replay", "/" + robot, domain, bridged)
        pubs[c.topic] = node.publisher(c.topic, c.msgtype)
    records: Iterator[tuple[Any, int, bytes]] = iter(
        source.reader.messages(connections=source.connections)
    )
    head = next(records, None)
    first = head[1] if head is not None else 0
    last_tick, sent = -1, 0

    def tick(t: int) -> None:
        nonlocal last_tick
        if ticks is not None and t > last_tick:
            ticks.put(cdr_clock(t))
            last_tick = t

    try:
        _wait(pubs, list(wait_for), ticks, delay, timeout, stop)
        start = time.time()
        while head is not None and not stop.is_set():
            now = first + int((time.time() - start) * speed * NS)
            while head is not None and head[1] <= now:
                connection, t, raw = head
                tick(t)
                pubs[connection.topic].put(bytes(raw))
                sent += 1
                head = next(records, None)
            tick(now if head is None else min(now, head[1] - 1))
            wait = (
                heartbeat
                if head is None
                else min(heartbeat, max(0.0, (head[1] - now) / speed / NS))
            )
            stop.wait(wait)
    finally:
        source.close()
        for node in (*nodes.values(), player):
            node.close()
    return sent


def _wait(
    pubs: dict[str, Ros2Publisher],
    topics: list[str],
    ticks: Ros2Publisher | None,
    delay: float,
    timeout: float,
    stop: threading.Event,
) -> None:
    """Until `delay` is over and every one of `topics` has a matching subscriber."""
    missing = sorted(set(topics) - set(pubs) - {CLOCK})
    if missing:
        raise DkError(f"replay: {missing[0]} is not a topic of the recording")
    every = {**pubs, **({CLOCK: ticks} if ticks is not None else {})}
    begin = time.monotonic()
    stop.wait(delay)
    while not all(every[t].publisher.matching_status.matching for t in topics):
        if time.monotonic() - begin > timeout:
            late = [t for t in topics if not every[t].publisher.matching_status.matching]
            raise DkError(f"replay: no subscriber for {', '.join(late)} within {timeout:g} s")
        if stop.wait(0.01):
            return
