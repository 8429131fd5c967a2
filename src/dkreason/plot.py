"""Plots, with matplotlib, kept out of the engine so monitoring never imports a plotting library:
`dkreason plot` (features' values over time, to pick a threshold) and `monitor --plot` (the
same panels with what the monitor said drawn on the features each formula reads).

One panel per feature, on the time axis of every other output (`t`, s from the start of the
recording, never an offset): numbers as lines, booleans and strings as steps between their
values; spans without a value shaded.  `monitor --plot` adds, on the panels of the features a
formula reads, its verdict (a line labelled with the formula's number and word), its witness
window, and the constants its comparisons hold those features to.  A legend names only what
is drawn.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

from .model import FeatureKey
from .monitor import WORDS, Event, MonitorRun
from .parse.formula import Compare, Num, Ref, Temporal, children, oriented
from .plan import FormulaPlan
from .progress import Verdict
from .progress.state import key
from .stream.processor import Violation
from .stream.units import NS, since

COLOURS = {True: "tab:green", False: "tab:red", None: "tab:grey"}
FORMATS = (".png", ".svg", ".pdf")


def plot_features(run: MonitorRun, keys: Sequence[FeatureKey], path: Path, title: str) -> None:
    """`dkreason plot`: the features' values over time (the run's states)."""
    fig, axes = _panels(run, keys)
    fig.suptitle(title, fontsize=9)
    _save(fig, path)


def plot(run: MonitorRun, events: list[Event], path: Path) -> None:
    """`monitor --plot`: the features the formulas read, with verdicts, witness windows,
    thresholds and stream constraint violations on the panels they concern."""
    formulas = run.monitor.plan.formulas
    keys = [f.feature.key for f in run.request.features]
    robust = sorted({e.formula for e in events if isinstance(e, Verdict) and e.robustness})
    fig, axes = _panels(run, keys, extra=1 if robust else 0)
    panel = dict(zip(keys, axes, strict=False))
    origin = run.start or Fraction(0)
    index = {f.text: n for n, f in enumerate(formulas)}
    drawn: dict[tuple[FeatureKey, float], list[str]] = {}
    for n, f in enumerate(formulas):
        for k, op, value in thresholds(i.tree for i in f.instances):
            drawn.setdefault((k, value), []).append(f"{op} {value:g} (#{n + 1})")
    for (k, value), said in drawn.items():
        if k in panel:
            panel[k].axhline(value, color="tab:purple", ls=":", lw=1, label="threshold")
            panel[k].annotate(
                ", ".join(said),
                (0, value),
                xycoords=("axes fraction", "data"),
                xytext=(3, 2),
                textcoords="offset points",
                fontsize=7,
                color="tab:purple",
                va="bottom",
                bbox={"fc": "white", "ec": "none", "alpha": 0.7, "pad": 1},
            )
    lines = []
    for e in (e for e in events if isinstance(e, Verdict) and not e.update):
        n = index.get(e.formula, 0)
        word = WORDS[e.verdict]
        when = "at the end" if e.t is None else f"at {since(e.t)}"
        who = [i.name for i in e.instances or () if e.verdict is False and i.verdict is False]
        by = f" ({', '.join(who)})" if who else ""
        lines.append(f"#{n + 1} {word} {when}{by}: {e.formula}")
        for k in concerned(formulas[n], e):
            ax = panel.get(k)
            if ax is None:
                continue
            if e.window is not None:
                lo, hi = (float(Fraction(w) - origin) for w in e.window)
                ax.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0, label="witness window")
            if e.t is not None and e.verdict is not None:
                ax.axvline(float(e.t), color=COLOURS[e.verdict], ls="--", lw=1.2)
                ax.annotate(
                    f"#{n + 1} {word}",
                    (float(e.t), 1),
                    xycoords=("data", "axes fraction"),
                    xytext=(-3, -3),
                    textcoords="offset points",
                    fontsize=7,
                    color=COLOURS[e.verdict],
                    ha="right",
                    va="top",
                    bbox={"fc": "white", "ec": "none", "alpha": 0.7, "pad": 1},
                )
    violated: dict[FeatureKey, list[float]] = {}
    for v in events:
        if isinstance(v, Violation) and v.t is not None and v.feature in panel:
            violated.setdefault(v.feature, []).append(float(v.t))
    for k, times in violated.items():
        # ticks along the panel's bottom edge (y in axes coordinates): the feature's y range
        # stays its values'
        panel[k].plot(
            times,
            [0.0] * len(times),
            ls="",
            marker=2,  # a tick rising from the edge
            transform=panel[k].get_xaxis_transform(),
            clip_on=False,
            color="tab:orange",
            ms=10,
            mew=1.5,
            label="stream constraint violated",
        )
    if robust:
        _robustness(run, axes[-1], [(n, f) for n, f in enumerate(formulas) if f.text in robust])
    for ax in axes:
        _legend(ax)
    fig.suptitle("\n".join(lines) or "dkreason monitor", fontsize=8, ha="left", x=0.01)
    _save(fig, path)


def concerned(formula: FormulaPlan, verdict: Verdict) -> set[FeatureKey]:
    """The features a verdict is drawn on: those its formula reads, or, when a quantified
    formula is violated, those of the instances that violated it (not every car's)."""
    instances = formula.instances
    if verdict.verdict is False and verdict.instances:
        violated = {i.bindings for i in verdict.instances if i.verdict is False}
        instances = tuple(i for i in instances if i.bindings in violated)
    return {k for i in instances for k in i.keys}


def thresholds(trees: Iterable[Any]) -> list[tuple[FeatureKey, str, float]]:
    """Each comparison of a feature with a constant (`Speed[car1] > 60`): the feature, the
    comparison as it reads with the feature on the left, and the constant; each once."""
    found: dict[tuple[FeatureKey, str, float], None] = {}

    def walk(node: Any) -> None:
        if isinstance(node, Compare):
            read = oriented(node, Ref)
            if read is not None and isinstance(read[2], Num):
                found[(key(read[0].feature), read[1], float(read[2].value))] = None
            return
        for child in children(node):
            walk(child)

    for tree in trees:
        walk(tree)
    return list(found)


def _robustness(run: MonitorRun, ax: Any, formulas: list[tuple[int, FormulaPlan]]) -> None:
    """`--robustness`: each formula's margin at every state, below 0 by how much it failed
    there, gaps where unknown.  Of `always S`, S's margin (where it dips, not the least of
    the future); of `forall`, the least of its objects' (`exists`: the greatest)."""
    from .progress.compile import scaled
    from .progress.robustness import margins

    origin = run.start or Fraction(0)
    times = [float(Fraction(t, NS) - origin) for t, _ in run.states]
    for n, f in formulas:
        lines = [
            _signal(margins(scaled(_body(i.tree), Fraction(NS)), run.states)) for i in f.instances
        ]
        pick = max if f.prefix and f.prefix[0].op == "exists" else min
        ys = [_nan_aware(pick, column) for column in zip(*lines, strict=True)]
        ax.step(times, ys, where="post", lw=1.2, label=f"#{n + 1} robustness")
    ax.axhline(0, color="black", lw=0.8)
    ax.set_ylabel("robustness", rotation=0, ha="right", va="center", fontsize=9)
    ax.grid(axis="y", alpha=0.3)


def _body(tree: Any) -> Any:
    """What an unbounded `always` holds of at each state; any other formula itself."""
    if isinstance(tree, Temporal) and tree.op == "always" and tree.interval.hi is None:
        return tree.arg
    return tree


def _signal(rho: list[Any]) -> list[float]:
    return [float("nan") if r is None else float(r) for r in rho]


def _nan_aware(pick: Any, values: Sequence[float]) -> float:
    """The least (or greatest) known value; unknown if one is unknown and could decide."""
    known = [v for v in values if v == v]
    if not known:
        return float("nan")
    best = pick(known)
    return best if len(known) == len(values) or (pick is min and best < 0) else float("nan")


def _panels(run: MonitorRun, keys: Sequence[FeatureKey], extra: int = 0) -> tuple[Any, list[Any]]:
    """A figure with a panel per feature, its values drawn and its spans without a value
    shaded, and `extra` panels below; the time axis relative, without an offset."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = max(len(keys) + extra, 1)
    fig, grid = plt.subplots(
        rows,
        1,
        sharex=True,
        squeeze=False,
        figsize=(10, 1.6 * rows + 1.2),
        layout="constrained",
    )
    axes = list(grid[:, 0])
    origin = run.start or Fraction(0)
    times = [float(Fraction(t, NS) - origin) for t, _ in run.states]
    for ax, k in zip(axes, keys, strict=False):
        values = [state.get(k) for _, state in run.states]
        _values(ax, times, values)
        _unknown(ax, times, values)
        ax.set_ylabel(str(k), rotation=0, ha="right", va="center", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    axes[-1].set_xlabel("t (s from the start of the recording)")
    axes[-1].ticklabel_format(axis="x", useOffset=False, style="plain")
    if times:  # the last state drawn as wide as a step, not as a tick at the edge
        span = max(times) - min(times) or 1.0
        axes[-1].set_xlim(min(times), max(times) + span / 50)
    return fig, axes


def _values(ax: Any, times: list[float], values: list[Any]) -> None:
    """Numbers as a line; booleans and strings as steps between their values, named."""
    seen = [v for v in values if v is not None]
    if not seen or not any(isinstance(v, bool | str) for v in seen):
        ys = [float(v) if v is not None else float("nan") for v in values]
        ax.step(times, ys, where="post", lw=1.4, color="tab:blue")
        ax.margins(y=0.2)
        return
    named = [
        None if v is None else str(v).lower() if isinstance(v, bool) else str(v) for v in values
    ]
    levels = (
        ["false", "true"]
        if all(isinstance(v, bool) for v in seen)
        else sorted({n for n in named if n is not None})
    )
    at = {level: n for n, level in enumerate(levels)}
    ys = [float("nan") if n is None else float(at[n]) for n in named]
    ax.step(times, ys, where="post", lw=1.4, color="tab:blue")
    ax.set_yticks(range(len(levels)), levels, fontsize=8)
    ax.set_ylim(-0.5, len(levels) - 0.5)


def _unknown(ax: Any, times: list[float], values: list[Any]) -> None:
    start = None
    for t, v in zip([*times, None], [*values, 0], strict=True):
        if v is None and start is None:
            start = t
        elif v is not None and start is not None:
            end = t if t is not None else times[-1]
            ax.axvspan(start, end, color="grey", alpha=0.25, lw=0, label="no value")
            start = None


def _legend(ax: Any) -> None:
    """A legend of what this panel shows, each kind once; none for a panel with nothing."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        unique = dict(zip(labels, handles, strict=True))
        ax.legend(unique.values(), unique.keys(), loc="best", fontsize=7)


def _save(fig: Any, path: Path) -> None:
    """Written atomically, as PNG, SVG or PDF by the file's suffix."""
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")  # the format follows the suffix
    try:
        fig.savefig(tmp, dpi=110)
        tmp.replace(path)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
