"""What a live monitor says besides verdicts and violations: the federation, or the ROS 2
graph, changed under it (a platform joined or left, a topic was subscribed or dropped, a
feature lost its last source)."""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from typing import Any

from ..model import stream_name
from ..monitor import Rerouted
from ..progress import Verdict
from ..stream.processor import Violation
from ..stream.units import seconds


@dataclass(frozen=True, slots=True)
class Change:
    """Something the federation did: joined, left, subscribed, unsubscribed, source_lost; or
    an instance of a quantified formula (`feature`: its bindings, `detail`: the formula)
    judged from now on, its object having joined the formula's sort; or (ROS 2, sim time)
    clock_reset: /clock went back, and the stream goes on from where it was."""

    event: str
    time: float | int | None  # s on the stream clock, like every event's; None before a clock
    platform: str
    detail: str = ""
    feature: str = ""
    topic: str = ""
    last_sample: float | int | None = None  # source_lost: s, the feature's newest sample

    def to_json(self) -> dict[str, Any]:
        out = {"event": self.event, "time": self.time, "platform": self.platform}
        out |= {
            k: v
            for k, v in (("feature", self.feature), ("topic", self.topic), ("detail", self.detail))
            if v
        }
        if self.last_sample is not None:
            out["last_sample"] = self.last_sample
        return out

    def __str__(self) -> str:
        when = "before start" if self.time is None else f"at {_shown(self.time)}"
        stream = stream_name(self.platform, self.topic)
        what = {
            "joined": f"platform {self.platform} joined",
            "left": f"platform {self.platform} left",
            "subscribed": f"subscribed to {stream} for {self.feature}",
            "unsubscribed": f"unsubscribed from {stream}",
            "source_lost": f"source lost: {self.feature} has no topic left",
            "instance": f"instance {self.feature} judged from now",
            "clock_reset": "/clock reset",
        }[self.event]
        if self.last_sample is not None:
            what += f"; its last sample is from {_shown(self.last_sample)}"
        return f"{when}: {what}" + (f" ({self.detail})" if self.detail else "")


Event = Verdict | Violation | Rerouted | Change


def change(
    event: str,
    ns: int | None,
    platform: str,
    detail: str = "",
    feature: str = "",
    topic: str = "",
    last_sample: int | None = None,
) -> Change:
    """A change seen at stream time `ns` (the monitors' clock), said in seconds."""
    return Change(
        event,
        None if ns is None else seconds(ns),
        platform,
        detail,
        feature,
        topic,
        None if last_sample is None else seconds(last_sample),
    )


def _shown(t: float) -> str:
    """A stream time (s) for people: seconds, or on an epoch clock (a live robot's wall
    clock) the UTC time, which says more than ten digits."""
    if t < 10**9:
        return f"{t} s"
    return (
        datetime.datetime.fromtimestamp(t, datetime.UTC)
        .isoformat(timespec="milliseconds")
        .replace("+00:00", "Z")
    )
