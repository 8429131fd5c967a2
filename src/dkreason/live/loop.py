"""The run loop both live monitors share (monitor.py over the federation, ros2.py over ROS 2).

Zenoh's threads only enqueue (inbox.py); the loop takes what has arrived in batches, lets the
monitor's protocol handle each event (`Feed.handle`: a sample put into the stream processor,
a platform or publisher come or gone), advances the stream to the protocol's watermark, and
yields the changes, violations and verdicts.  It ends when every formula is decided, the
stream clock passes `until`, `duration` wall seconds are over, the stream ends (`Feed.over`)
or `stop` is set; then the end verdicts follow.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any, Protocol

from ..monitor import Monitor
from ..stream.processor import StreamProcessor
from ..stream.sources import Message, Wanted
from .change import Event
from .inbox import Inbox


class Feed(Protocol):
    """A live monitor's protocol, as the loop sees it."""

    @property
    def inbox(self) -> Inbox: ...

    @property
    def stop(self) -> threading.Event: ...

    def handle(self, event: Any) -> list[Event]:
        """An event from zenoh's threads taken (a bad one logged and dropped): the changes
        it made."""
        ...

    def now(self) -> int | None:
        """The stream clock (ns) `until` is read on; None before it is known."""
        ...

    def watermark(self) -> int | None:
        """Up to when every sample has been taken (ns); None: not known yet."""
        ...

    def idle(self) -> float:
        """How long to wait for the next event (s)."""
        ...

    def over(self) -> bool:
        """Nothing more will come: the stream ends, as a recording does."""
        ...

    def tick(self) -> None:
        """Once a pass, after its events: what the protocol checks as time goes by."""
        ...

    def close(self) -> None:
        """Every subscription undeclared."""
        ...


def run(
    monitor: Monitor,
    processor: StreamProcessor,
    feed: Feed,
    end: int | None = None,
    duration: float | None = None,
) -> Iterator[Event]:
    """Events as they happen, until every formula is decided, the stream clock passes `end`
    (ns), `duration` (wall s) is over, the feed is over or its `stop` is set; then the end
    verdicts."""
    stop_at = None if duration is None else time.monotonic() + duration
    try:
        while not feed.stop.is_set() and not monitor.done:
            if stop_at is not None and time.monotonic() >= stop_at:
                break
            if feed.over():
                break
            now = feed.now()
            if end is not None and now is not None and now > end:
                break
            changes = [c for event in feed.inbox.drain(feed.idle()) for c in feed.handle(event)]
            feed.tick()
            mark = feed.watermark()
            if mark is not None:
                processor.advance(mark if end is None else min(mark, end))
            yield from changes
            yield from monitor.events()
    finally:
        feed.close()
    yield from monitor.finish()


class LiveSource:
    """The stream processor's view of the network: nothing known before messages come."""

    name = "<live>"

    def types(self) -> dict[str, str]:
        return {}

    def check_field(self, topic: str, field: str) -> str | None:
        return None

    def first_record(self) -> int | None:
        return None  # the stream processor starts the time axis at the first sample put

    def last_record(self) -> int | None:
        return None

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        return None

    def messages(self, wanted: Wanted) -> Iterator[Message]:
        return iter(())

    def count(self, topics: set[str] | None) -> int | None:
        return None

    def close(self) -> None:
        pass


def logged(n: int) -> bool:
    """1, 10, 100, 1000…: how often a repeated warning (a peer's rejected payloads) is worth
    a line."""
    return n == 1 or (n % 10 == 0 and logged(n // 10))
