"""A recording replayed at its own pace (`monitor --speed`), so a viewer watching the run
(Foxglove) sees it unfold as the robot lived it, or `speed` times faster."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

from .sources import Message
from .units import NS


def paced(
    messages: Iterator[Message],
    speed: float,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Iterator[Message]:
    """`messages`, each yielded no sooner than `(its record time - the first's) / speed`
    seconds of `clock` after the first was."""
    start: float | None = None
    first = 0
    for message in messages:
        if start is None:
            start, first = clock(), message[1]
        else:
            wait = start + (message[1] - first) / NS / speed - clock()
            if wait > 0:
                sleep(wait)
        yield message
