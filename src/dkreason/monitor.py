"""Close the loop (thesis 2.3.2, 4.4): formulas → stream request → Stream Processor → Formula
Progressor → verdicts, from a recording or any other source.

    monitor = Monitor(km, ["forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] "
                           "Speed[c] <= 60)"], StreamPolicy())
    for event in monitor.run(open_source(Path("traffic.mcap"))): ...   # Verdict | Violation
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

from .errors import DkError
from .manager import KnowledgeManager
from .model import FeatureRequest, StreamRequest
from .progress import Progressor, Verdict
from .stream.processor import StreamPolicy, StreamProcessor, Violation, seconds
from .stream.sources import NS, Source

Event = Verdict | Violation


class Monitor:
    def __init__(self, km: KnowledgeManager, formulas: list[str], policy: StreamPolicy) -> None:
        self.km, self.formulas, self.policy = km, formulas, policy
        self.request = combined_request(km, formulas)
        self.states: list[tuple[int, dict[str, Any]]] = []
        self.keep_states = False

    def run(self, source: Source, progress: Callable[[int], None] | None = None
            ) -> Iterator[Event]:
        """Events as they happen: violations as seen, verdicts as decided, the rest at the end.
        An error in the source comes after every event decided before it."""
        progressor = Progressor.with_knowledge(self.km, unit=Fraction(1, NS))
        for f in self.formulas:
            progressor.add(f)
        out: list[Event] = []

        def on_state(time: int, values: dict[str, Any]) -> None:
            if self.keep_states:
                self.states.append((time, dict(values)))
            out.extend(in_seconds(v) for v in progressor.step(time, values))

        try:
            processor = StreamProcessor(self.request, self.policy, source, on_state, out.append)
        except BaseException:
            source.close()
            raise
        try:
            feed = processor.feed
            for n, (topic, available, valid, values) in enumerate(
                    source.messages(processor.wanted), 1):
                feed(topic, available, valid, values)
                if out:
                    yield from out
                    out.clear()
                if progress is not None and not n & 4095:
                    progress(n)
        except DkError:  # damage or bad data: first what the messages before it decided
            processor.finish()
            yield from out
            raise
        finally:
            source.close()
        processor.finish()
        out.extend(in_seconds(v) for v in progressor.finish())
        yield from out


def combined_request(km: KnowledgeManager, formulas: list[str]) -> StreamRequest:
    """One request for several formulas: each ground feature once."""
    features: dict[str, FeatureRequest] = {}
    for f in formulas:
        for fr in km.check_formula(f).features:
            features.setdefault(fr.feature.key, fr)
    return StreamRequest("; ".join(formulas), km.local, tuple(features.values()))


def in_seconds(v: Verdict) -> Verdict:
    """The progressor runs in nanoseconds; people read seconds."""
    unknown = tuple(dataclasses.replace(u, start=seconds(u.start), end=seconds(u.end))
                    for u in v.unknown)
    return dataclasses.replace(v, time=None if v.time is None else seconds(v.time),
                               unknown=unknown)


def plot(monitor: Monitor, events: list[Event], path: Path) -> None:
    """Each feature over time (unobserved spans shaded), verdicts as vertical lines, stream
    constraint violations as orange ticks; written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["".join(f.feature.key.split()) for f in monitor.request.features]
    fig, axes = plt.subplots(max(len(keys), 1), 1, sharex=True, squeeze=False,
                             figsize=(10, 1.5 * max(len(keys), 1) + 1.6))
    times = [float(seconds(t)) for t, _ in monitor.states]
    for ax, key in zip(axes[:, 0], keys, strict=False):
        values = [state.get(key) for _, state in monitor.states]
        ys = [float(v) if v is not None else float("nan") for v in values]
        ax.step(times, ys, where="post", lw=1.4, color="tab:blue")
        ax.margins(y=0.25)
        start = None
        for t, v in zip([*times, None], [*values, 0], strict=True):
            if v is None and start is None:
                start = t
            elif v is not None and start is not None:
                ax.axvspan(start, t if t is not None else times[-1], color="grey", alpha=0.25,
                           lw=0, label="unobserved")
                start = None
        ticks = [float(seconds(e.time)) for e in events
                 if isinstance(e, Violation) and e.feature == key]
        if ticks:
            ax.plot(ticks, [ax.get_ylim()[0]] * len(ticks), "|", color="tab:orange", ms=10,
                    label="constraint violated")
        ax.set_ylabel(key, rotation=0, ha="right", va="center", fontsize=9)
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            unique = dict(zip(labels, handles, strict=True))
            ax.legend(unique.values(), unique.keys(), loc="upper right", fontsize=7)
    lines = []
    for e in events:
        if isinstance(e, Verdict) and e.verdict is not None:
            color = "tab:green" if e.verdict else "tab:red"
            for ax in axes[:, 0]:
                ax.axvline(float(e.time), color=color, ls="--", lw=1.2)
            word = "held" if e.verdict else "violated"
            lines.append(f"{word} at {e.time} s: {e.formula}")
    unknown = [e for e in events if isinstance(e, Verdict) and e.verdict is None]
    lines += [f"unknown at end: {e.formula}" for e in unknown]
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("\n".join(lines) or "dkreason monitor", fontsize=8, ha="left", x=0.01)
    fig.tight_layout(rect=(0, 0, 1, 0.97 - 0.02 * len(lines)))
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
