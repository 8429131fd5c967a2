"""Verdicts and violations published as they come (`monitor --publish-verdicts`): as JSON on
the federation's keys, and with `--ros2` as a ROS 2 topic its robots can subscribe to."""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from typing import Any

from ..model import FeatureKey
from ..monitor import Rerouted
from ..progress import Verdict
from ..stream.processor import Violation
from .ros2node import Ros2Node

VERDICTS = "/dkreason/verdicts"


def cdr_string(text: str) -> bytes:
    """A std_msgs/msg/String in CDR (little endian)."""
    data = text.encode()
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(data) + 1) + data + b"\x00"


class Announcer:
    """Verdicts and violations back onto the network: JSON on `dkreason/verdicts/<formula
    id>` (`f1`, `f2`, … in the order the formulas were given), a violation or a re-route (a
    source set aside or taken back) on the id of each formula reading its feature
    (`violations` when none does), and with `ros2` the same JSON
    once as std_msgs/msg/String on the ROS 2 topic `/dkreason/verdicts`."""

    def __init__(
        self,
        session: Any,
        formulas: list[str],
        ros2: bool = False,
        domain: int = 0,
        labelled: Callable[[], bool] | None = None,
        reads: Callable[[FeatureKey], list[str]] | None = None,
    ) -> None:
        """`labelled`: whether the robots' attachments are in Jazzy's first layout (the ROS 2
        monitor says what it has seen), which their subscribers then expect of ours too;
        `reads`: the formulas (as written) that read a feature."""
        self.session, self.labelled, self.reads = session, labelled, reads
        self.ids = {text: f"f{n}" for n, text in enumerate(formulas, 1)}
        self.readers: dict[FeatureKey, list[str]] = {}  # feature → formula ids, as asked
        self.node = Ros2Node(session, "dkreason_monitor", "/", domain) if ros2 else None
        self.topic = self.node.publisher(VERDICTS, "std_msgs/msg/String") if self.node else None

    def _ids(self, event: Verdict | Violation | Rerouted) -> list[str]:
        if isinstance(event, Verdict):
            return [self.ids.get(event.formula, "other")]
        ids = self.readers.get(event.feature)
        if ids is None:
            texts = self.reads(event.feature) if self.reads is not None else []
            ids = self.readers[event.feature] = [self.ids[t] for t in texts if t in self.ids]
        return ids or ["violations"]

    def __call__(self, event: Any) -> None:
        if not isinstance(event, Verdict | Violation | Rerouted):
            return
        ids = self._ids(event)
        for fid in ids:
            self.session.put(
                f"dkreason/verdicts/{fid}",
                json.dumps(
                    {"id": fid, **event.to_json()}, ensure_ascii=False, default=str
                ).encode(),
            )
        if self.topic is not None:
            self.topic.node.labelled = self.labelled is not None and self.labelled()
            self.topic.put(
                cdr_string(
                    json.dumps({"ids": ids, **event.to_json()}, ensure_ascii=False, default=str)
                )
            )

    def close(self) -> None:
        if self.node is not None:
            self.node.close()
