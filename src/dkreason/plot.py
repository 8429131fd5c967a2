"""`--plot`: a monitored run drawn with matplotlib, kept out of the engine so monitoring never
imports a plotting library."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

from .monitor import WORDS, Event, MonitorRun
from .progress import Verdict
from .stream.processor import Violation
from .stream.units import NS, since


def plot(run: MonitorRun, events: list[Event], path: Path) -> None:
    """Each feature over time (unobserved spans shaded), verdicts as vertical lines, stream
    constraint violations as orange ticks, on the time axis of every other output (`t`, s from
    the start of the recording); written atomically, as PNG, SVG or PDF by the file's
    suffix."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [f.feature.key for f in run.request.features]
    fig, axes = plt.subplots(
        max(len(keys), 1),
        1,
        sharex=True,
        squeeze=False,
        figsize=(10, 1.5 * max(len(keys), 1) + 1.6),
    )
    origin = run.start or Fraction(0)
    times = [float(Fraction(t, NS) - origin) for t, _ in run.states]
    for ax, key in zip(axes[:, 0], keys, strict=False):
        values = [state.get(key) for _, state in run.states]
        ys = [float(v) if v is not None else float("nan") for v in values]
        ax.step(times, ys, where="post", lw=1.4, color="tab:blue")
        ax.margins(y=0.25)
        start = None
        for t, v in zip([*times, None], [*values, 0], strict=True):
            if v is None and start is None:
                start = t
            elif v is not None and start is not None:
                ax.axvspan(
                    start,
                    t if t is not None else times[-1],
                    color="grey",
                    alpha=0.25,
                    lw=0,
                    label="unobserved",
                )
                start = None
        ticks = [
            float(e.t)
            for e in events
            if isinstance(e, Violation) and e.feature == key and e.t is not None
        ]
        if ticks:
            ax.plot(
                ticks,
                [ax.get_ylim()[0]] * len(ticks),
                "|",
                color="tab:orange",
                ms=10,
                label="constraint violated",
            )
        ax.set_ylabel(str(key), rotation=0, ha="right", va="center", fontsize=9)
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            unique = dict(zip(labels, handles, strict=True))
            ax.legend(unique.values(), unique.keys(), loc="upper right", fontsize=7)
    lines = []
    verdicts = [e for e in events if isinstance(e, Verdict) and not e.update]  # once each
    for e in verdicts:
        if e.verdict is not None and e.t is not None:
            color = "tab:green" if e.verdict else "tab:red"
            for ax in axes[:, 0]:
                ax.axvline(float(e.t), color=color, ls="--", lw=1.2)
            word = WORDS[e.verdict]
            lines.append(f"{word} at {since(e.t)}: {e.formula}")
    unknown = [e for e in verdicts if e.verdict is None]
    lines += [f"unknown at end: {e.formula}" for e in unknown]
    axes[-1, 0].set_xlabel("t (s from the start of the recording)")
    fig.suptitle("\n".join(lines) or "dkreason monitor", fontsize=8, ha="left", x=0.01)
    fig.tight_layout(rect=(0, 0, 1, 0.97 - 0.02 * len(lines)))
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")  # the format follows the suffix
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
