"""Events from zenoh's threads to the monitor's loop.

`queue.Queue` takes its lock (and wakes the consumer) on every put and get: at tens of
thousands of samples a second that lock, contended between zenoh's threads and the monitor,
costs more than the monitor's own work on a sample.  An `Inbox` is a deque (appends and pops
are atomic) and two events used only at the edges: `arrived` wakes the monitor when it found
nothing and sleeps, `room` wakes a producer that found the inbox full.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any

BATCH = 1000  # events handled before the watermark is computed and the stream advanced


class Inbox:
    def __init__(self, limit: int = 0) -> None:
        """`limit`: at most this many events wait (0: no limit)."""
        self.items: deque[Any] = deque()
        self.limit = limit
        self.arrived = threading.Event()
        self.room = threading.Event()
        self.sleeping = False  # the consumer waits on `arrived`

    def put(self, item: Any, timeout: float = 0.0) -> bool:
        """Add an event (any thread); with a limit, wait up to `timeout` s for room, then
        give up: False, the event is not added."""
        items = self.items
        if self.limit and len(items) >= self.limit:
            self.room.clear()  # cleared before the length is read again: a drain sets it
            if len(items) >= self.limit and not self.room.wait(timeout):
                return False
        items.append(item)
        if self.sleeping:  # read after the append: a consumer that set it sees the event
            self.arrived.set()
        return True

    def drain(self, timeout: float, most: int = BATCH) -> list[Any]:
        """What has arrived, up to `most` events, waiting up to `timeout` s for the first (the
        consumer's thread): the watermark, the processor's advance and the verdicts are paid
        once a batch, not once an event."""
        items = self.items
        if not items:
            self.sleeping = True
            if not items:  # read after the flag is set: an event put since is seen here
                self.arrived.wait(timeout)
            self.sleeping = False
            self.arrived.clear()
        batch = [items.popleft() for _ in range(min(most, len(items)))]
        if self.limit:
            self.room.set()
        return batch
