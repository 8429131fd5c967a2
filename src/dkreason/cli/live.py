"""The live commands: `monitor --live` (a federation of `serve` nodes over Zenoh), `monitor
--ros2` (ROS 2 robots over rmw_zenoh) and `serve` (a platform node)."""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
from collections import Counter
from typing import Any

from ..errors import DkError
from ..live.change import Change
from ..live.monitor import LiveMonitor, configured
from ..live.publish import Announcer
from ..live.record import Recorder
from ..live.ros2 import Ros2Monitor
from ..live.serve import PlatformNode
from ..live.session import open_session
from ..live.signing import signer, trusted_keys
from ..live.viewer import Viewer
from ..live.wire import Limits
from ..manager import KnowledgeManager
from ..monitor import Monitor, Watch
from ..progress import Verdict
from ..stream.binding import remaps
from ..stream.policy import StreamPolicy
from ..stream.processor import Violation
from ..stream.sources import open_source
from ..stream.typestore import load_typestore, msg_types
from . import args as a
from . import render
from .options import formulas as read_formulas


def monitor_live(args: argparse.Namespace, policy: StreamPolicy) -> int:
    if args.source or args.plot is not None:
        raise DkError("--live takes no --source and no --plot")
    _logging()
    formulas = read_formulas(args)
    km = KnowledgeManager.from_config(args.config, live=True)  # read before the session opens
    trust = trusted_keys(args.trust, configured(km)) if args.trust is not None else None
    limits = Limits(topics=args.max_peer_topics, objects=args.max_peer_objects)
    viewer = _viewer(args)
    session = _session(args)
    try:
        monitor = LiveMonitor(
            km,
            formulas,
            policy,
            session,
            args.wait,
            trust=trust,
            limits=limits,
            watch=_watch(viewer),
        )
        _on_signals(lambda *_: monitor.stop.set())
        return _report(
            args,
            monitor.run(args.until, args.duration),
            session,
            [f.text for f in monitor.formulas],
            ros2=False,
            reads=lambda key: _reading(monitor.monitor, key),
            viewer=viewer,
        )
    finally:
        session.close()
        if viewer is not None:
            viewer.close()


def monitor_ros2(args: argparse.Namespace, policy: StreamPolicy) -> int:
    if args.source or args.plot is not None or args.live:
        raise DkError("--ros2 takes no --source, --plot or --live")
    _logging()
    bind = {}
    for given in args.bind:
        platform, sep, namespace = given.partition("=")
        if not sep or not namespace.startswith("/"):
            raise DkError(f"--bind {given!r}: expected PLATFORM=/NAMESPACE")
        bind[platform] = namespace
    domain = a.ros_domain(args.domain)
    km = KnowledgeManager.from_config(args.config)
    unknown = sorted(set(bind) - set(km.platforms))
    if unknown:
        raise DkError(
            f"--bind {unknown[0]}: not a platform of the config (platforms: "
            f"{', '.join(sorted(km.platforms))})"
        )
    store = load_typestore(msg_types(args.msg), False, args.typestore or "ros2_jazzy")
    formulas = read_formulas(args)
    viewer = _viewer(args)
    recorder = Recorder(args.record, store, force=args.force) if args.record is not None else None
    session = _session(args)
    try:
        monitor = Ros2Monitor(
            km,
            list(formulas),
            policy,
            session,
            store=store,
            domain=domain,
            bridge=args.bridge,
            bind=bind,
            remap=remaps(args.remap),
            sim_time=args.sim_time,
            recorder=recorder,
            watch=_watch(viewer),
        )
        recorder = None  # the monitor closes it
        _on_signals(lambda *_: monitor.stop.set())
        return _report(
            args,
            monitor.run(args.until, args.duration, args.wait),
            session,
            [f.text for f in monitor.monitor.plan.formulas],
            ros2=True,
            domain=domain,
            labelled=lambda: monitor.labelled,
            reads=lambda key: _reading(monitor.monitor, key),
            viewer=viewer,
        )
    finally:
        if recorder is not None:
            recorder.close()
        session.close()
        if viewer is not None:
            viewer.close()


def _viewer(args: argparse.Namespace) -> Viewer | None:
    """`--foxglove`: the run served to Foxglove from the start (live data does not wait)."""
    if args.foxglove is None:
        return None
    viewer = Viewer(args.foxglove)
    print(f"serving Foxglove on {viewer.url}", file=sys.stderr, flush=True)
    return viewer


def _watch(viewer: Viewer | None) -> Watch | None:
    return None if viewer is None else viewer.state


def _reading(monitor: Monitor | None, key: Any) -> list[str]:
    """The formulas (as written) of a running Monitor that read a feature (none before it
    runs)."""
    return [f.text for f in monitor.plan.formulas if key in f.keys] if monitor is not None else []


def _report(
    args: argparse.Namespace,
    events: Any,
    session: Any,
    formulas: list[str],
    ros2: bool,
    domain: int = 0,
    labelled: Any = None,
    reads: Any = None,
    viewer: Viewer | None = None,
) -> int:
    """A live run's events printed (and published with --publish-verdicts) as they come."""
    announce = (
        Announcer(session, formulas, ros2, domain, labelled, reads)
        if args.publish_verdicts
        else None
    )
    verdicts: list[Verdict] = []
    violations: Counter[str] = Counter()
    try:
        for event in events:
            if announce is not None:
                announce(event)
            if viewer is not None:
                viewer.event(event)
            if isinstance(event, Change):
                print(
                    json.dumps(event.to_json(), ensure_ascii=False) if args.json else str(event),
                    flush=True,
                )
                continue
            if isinstance(event, Verdict):
                verdicts.append(event)
            elif isinstance(event, Violation):
                violations[event.constraint] += 1
            render.event(event, args.json)
    finally:
        if announce is not None:
            announce.close()
    if not args.json:
        render.summary(verdicts, violations)
    return render.exit_status(
        [v.verdict for v in verdicts], args.fail_on_constraint and bool(violations)
    )


def serve(args: argparse.Namespace) -> int:
    _logging()
    km = KnowledgeManager.from_config(args.config)
    source = open_source(args.source, args.msg, args.typestore) if args.source is not None else None
    records = getattr(source, "records", None)
    if source is not None and records is None:
        raise DkError(f"{source.name}: a damaged recording cannot be replayed live")
    sign = signer(args.sign) if args.sign is not None else None
    session = _session(args)
    node = PlatformNode(km, session, args.heartbeat, sign)
    print(f"serving {km.local}: {len(km.list_topics())} topic specification(s)", flush=True)
    _on_signals(_interrupt)
    try:
        if records is None:
            node.serve(None, args.origin, args.speed)
        elif str(args.source) == "-":
            node.feed(records())
        else:
            node.serve(records(), args.origin, args.speed)
    except KeyboardInterrupt:
        pass
    finally:
        node.close()
        session.close()
        if source is not None:
            source.close()
    return 0


def _logging() -> None:
    logging.basicConfig(stream=sys.stderr, level=logging.INFO, format="%(name)s: %(message)s")


def _session(args: argparse.Namespace) -> Any:
    return open_session(args.connect, args.listen, args.zenoh_config)


def _on_signals(handler: Any) -> None:
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def _interrupt(*_: object) -> None:
    raise KeyboardInterrupt
