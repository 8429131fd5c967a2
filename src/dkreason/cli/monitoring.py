"""The monitoring commands over data at rest: monitor (recordings; --live and --ros2 go to
cli/live.py), progress (a state file) and info (what recordings hold)."""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

from ..errors import DkError, one_line
from ..manager import KnowledgeManager
from ..parse.formula import parse_formula
from ..progress import Progressor, Verdict
from ..progress.state import feature_uses
from ..progress.statefile import read_states
from ..stream.info import render as render_info
from ..stream.policy import DEFAULT
from ..stream.processor import Violation
from . import live, render
from .options import formulas, policy


def monitor(args: argparse.Namespace) -> int:
    stream_policy = policy(args)
    if args.plot is not None and not args.plot.parent.is_dir():
        raise DkError(f"--plot {args.plot}: no such directory {args.plot.parent}")
    if args.plot is not None and args.plot.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise DkError(f"--plot {args.plot}: name a .png, .svg or .pdf file")
    ros2_only = [
        flag
        for flag, given in (
            ("--bridge", args.bridge),
            ("--bind", args.bind),
            ("--sim-time", args.sim_time),
            ("--domain", args.domain),
        )
        if given not in (False, [], None)
    ]
    if ros2_only and not args.ros2:
        raise DkError(f"{ros2_only[0]} is for --ros2")
    if args.publish_verdicts and not (args.live or args.ros2):
        raise DkError("--publish-verdicts is for --live or --ros2")
    if args.live and args.record is not None:
        raise DkError("--record is for recordings and --ros2 (--live samples are no ROS messages)")
    if args.clips is not None and (args.live or args.ros2):
        raise DkError("--clips is for recordings (--source)")
    if args.robustness and (args.live or args.ros2):
        raise DkError("--robustness is for recordings (--source)")
    if args.speed is not None and (args.live or args.ros2):
        raise DkError("--speed is for recordings (--source): live data comes at its own pace")
    if args.ros2:
        return live.monitor_ros2(args, stream_policy)
    if args.live:
        return live.monitor_live(args, stream_policy)
    if not args.source:
        raise DkError("monitor needs --source RECORDING, or --live")
    km = KnowledgeManager.from_config(args.config)
    run = km.monitor(
        formulas(args),
        args.source,
        stream_policy,
        remap=args.remap,
        clock=args.clock,
        msg=args.msg,
        typestore=args.typestore,
        keep_states=args.plot is not None,
        record=args.record,
        clips=args.clips,
        margin=args.clip_margin,
        robustness=args.robustness,
        foxglove=args.foxglove,
        speed=args.speed,
        force=args.force,
    )
    with run:
        return _monitored(args, run)


def _monitored(args: argparse.Namespace, run: Any) -> int:
    for topic, features in run.absent.items():
        print(f"warning: {topic} (for {', '.join(features)}) is in no recording", file=sys.stderr)
    for note in run.notes:
        print(f"note: {note}", file=sys.stderr)
    if not args.json:
        print(render.request(run.request), flush=True)
    if args.json:  # every warning of the request (its text said them otherwise)
        render.formula_warnings(run.request.warnings, args.json)
    if run.watcher is not None:
        print(
            f"serving Foxglove on {run.watcher.url}: the replay starts when it subscribes to "
            "a topic",
            file=sys.stderr,
            flush=True,
        )
    events: list[Any] = []
    error = None
    with render.progress_bar(run.count() if not args.json else None, not args.json) as tick:
        try:
            for event in run.events(tick):
                events.append(event)
                render.event(event, args.json)
        except DkError as exc:
            error = exc
    verdicts = [e for e in events if isinstance(e, Verdict)]
    violations = Counter(e.constraint for e in events if isinstance(e, Violation))
    if not args.json:
        render.summary(verdicts, violations)
    if args.plot is not None and run.states:
        _plot(run, events, args.plot, args.json)
    if not args.json:
        if args.record is not None:
            print(f"recorded to {args.record}")
        for path, verdict in getattr(run, "written", ()):
            print(f"clip {path}: {verdict.formula}")
    if error is not None:
        raise error
    return render.exit_status(
        [v.verdict for v in verdicts], args.fail_on_constraint and bool(violations)
    )


def _plot(run: Any, events: list[Any], path: Path, quiet: bool) -> None:
    """`--plot`: a failure to draw is one error line; the verdicts' exit status stands."""
    from ..plot import plot

    try:
        plot(run, events, path)
    except Exception as exc:  # matplotlib's errors are of any kind (fonts, disk, backends)
        print(f"error: --plot {path}: {one_line(str(exc)) or type(exc).__name__}", file=sys.stderr)
        return
    if not quiet:
        print(f"plot written to {path}")


def plot(args: argparse.Namespace) -> int:
    KnowledgeManager.from_config(args.config).plot(
        args.features,
        args.source,
        args.output,
        remap=args.remap,
        clock=args.clock,
        msg=args.msg,
        typestore=args.typestore,
    )
    print(f"plot written to {args.output}")
    return 0


def progress(args: argparse.Namespace) -> int:
    progressor = Progressor(
        end_of_data=args.end_of_data or DEFAULT.end_of_data, robustness=args.robustness
    )
    planned = KnowledgeManager.from_config(args.config).plan(args.formulas) if args.config else None
    trees = (
        [(f.text, f.tree) for f in planned.formulas]
        if planned
        else [(f, parse_formula(f)) for f in args.formulas]
    )
    for text, tree in trees:
        progressor.add(text, tree if planned else None)
    render.formula_warnings(planned.warnings if planned else progressor.warnings, args.json)
    used = {k: use for k, (use, _) in feature_uses(trees).items()}
    verdicts = []

    def emit(batch: list[Verdict]) -> None:
        for v in batch:
            verdicts.append(v)
            if args.json:
                print(json.dumps(v.to_json(), ensure_ascii=False, default=str), flush=True)
            else:
                when = "at end" if v.at_end else "at"
                print(
                    f"{when} {v.time}: {render.shout(v.verdict)}  {v.formula}"
                    + (f"\n    {v.witness}" if v.witness else "")
                    + (f"\n    robustness: {v.robustness.text()}" if v.robustness else ""),
                    flush=True,
                )

    for time, values in read_states(args.states, used):
        emit(progressor.step(time, values))
    emit(progressor.finish())
    return render.exit_status([v.verdict for v in verdicts])


def info(args: argparse.Namespace) -> int:
    if not args.source:
        if not args.config:
            raise DkError("info needs recordings, or --config to list the features")
        return _features(KnowledgeManager.from_config(args.config), args.json)
    if args.config:
        infos, binds = KnowledgeManager.from_config(args.config).info(
            args.source,
            fields=args.fields,
            msg=args.msg,
            typestore=args.typestore,
            timing=args.timing,
        )
    else:
        infos, binds = (
            KnowledgeManager.describe(
                args.source,
                fields=args.fields,
                msg=args.msg,
                typestore=args.typestore,
                timing=args.timing,
            ),
            None,
        )
    if args.json:
        print(
            json.dumps(
                {
                    "recordings": [i.to_json() for i in infos],
                    "specs": [b.to_json() for b in binds or ()],
                },
                ensure_ascii=False,
            )
        )
    else:
        print(render_info(infos, binds))
    return 0


def _features(km: KnowledgeManager, as_json: bool) -> int:
    """Each platform's features: signature and origin (class pattern or adapter rule)."""
    found = km.list_features()
    if as_json:
        print(json.dumps({"features": [f.to_json() for f in found]}, ensure_ascii=False))
        return 0
    width = max((len(str(f)) for f in found), default=0)
    for name in km.platforms:
        print(f"platform {name}:")
        for f in (f for f in found if f.platform == name):
            print(f"  {str(f):<{width}}  {f.origin}")
    return 0
