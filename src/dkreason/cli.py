"""`dkreason`: a thin CLI over KnowledgeManager.  Every DkError is one line on stderr, exit 2.

Heavy imports (rdflib, pyDatalog, lark) happen inside the commands so `--help` starts fast.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from .errors import DkError, one_line

if TYPE_CHECKING:
    from .manager import KnowledgeManager
    from .model import StreamRequest


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, like every other input error
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


EXIT_STATUS = (
    "exit status: 0 every formula held, 1 one was violated, 2 bad input (one line "
    "on stderr), 3 one stayed undecided"
)


def main(argv: Sequence[str] | None = None) -> int:
    parser = _build()
    args = parser.parse_args(argv)

    try:
        code: int = args.run(args)
        sys.stdout.flush()
        return code
    except DkError as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as ROS tools do
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


class _Version(argparse.Action):
    """--version, reading the installed version only when asked (importlib.metadata costs
    more than the rest of `dkreason --help`)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: Any) -> NoReturn:
        from importlib.metadata import version

        print(f"dkreason {version('dkreason')}")
        parser.exit(0)


def _build() -> _Parser:
    from .stream import TYPESTORES

    parser = _Parser(prog="dkreason", description=__doc__.split("\n")[0] if __doc__ else None)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(required=True, metavar="COMMAND", parser_class=_Parser)

    def config(p: argparse.ArgumentParser) -> None:
        p.add_argument("--config", required=True, type=Path, help="TOML config file")

    def definitions(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--msg",
            type=Path,
            action="append",
            default=[],
            metavar="FILE",
            help="a pkg/msg/Name.msg definition, for recordings that store none or to "
            "replace a wrong one they store "
            "(repeatable)",
        )
        p.add_argument(
            "--typestore",
            choices=TYPESTORES,
            help="rosbags' standard message definitions for recordings that store "
            "none (default ros1_noetic for .bag, else ros2_humble)",
        )

    def network(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--connect",
            action="append",
            default=[],
            metavar="ENDPOINT",
            help="Zenoh endpoint to connect to, e.g. tcp/10.0.0.2:7447 (repeatable)",
        )
        p.add_argument(
            "--listen",
            action="append",
            default=[],
            metavar="ENDPOINT",
            help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)",
        )
        p.add_argument(
            "--zenoh-config",
            metavar="FILE",
            help="Zenoh config file (TLS, access control); endpoints still apply",
        )

    p = sub.add_parser("match", help="the topics each feature of a formula is read from")
    config(p)
    p.add_argument("--json", action="store_true", help="print the stream request as JSON")
    p.add_argument(
        "--stats",
        action="store_true",
        help="on stderr: load and match times, and the rows of every stored "
        "relation (told facts and materialized views)",
    )
    p.add_argument("formula")
    p.set_defaults(run=_match)

    p = sub.add_parser("progress", help="verdicts of formulas over a JSON-lines state file")
    p.add_argument(
        "--states",
        required=True,
        type=Path,
        help='JSON lines: {"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5}}',
    )
    p.add_argument("--config", type=Path, help="TOML config: quantifiers range over its objects")
    p.add_argument("--json", action="store_true", help="one JSON line per formula")
    p.add_argument("formulas", nargs="+", metavar="FORMULA")
    p.set_defaults(run=_progress)

    p = sub.add_parser(
        "monitor",
        help="verdicts of formulas over a robot recording, or live",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"{EXIT_STATUS}\n\n"
        "example:\n  dkreason monitor --config examples/federation.toml --source "
        "examples/traffic/recording --delay 100ms \\\n    'forall c in Car: always "
        "(Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)'",
    )
    config(p)
    p.add_argument(
        "--source",
        action="append",
        default=[],
        metavar="[PLATFORM=]PATH",
        help="ROS 1 .bag, ROS 2 bag folder or .mcap/.db3 file, or .jsonl messages; "
        "repeat for several recordings (merged by record time); PLATFORM= "
        "binds a recording's topics to that platform's specs only",
    )
    p.add_argument(
        "--remap",
        action="append",
        default=[],
        metavar="FROM:=TO",
        help="read recording topic FROM as TO (repeatable)",
    )
    p.add_argument(
        "--clock",
        choices=("auto", "header", "record"),
        default="auto",
        help="valid time from header.stamp or the record time; auto: the stamps, "
        "unless they run on another clock (simulated time), said in one line "
        "(default auto)",
    )
    definitions(p)
    p.add_argument(
        "--live",
        action="store_true",
        help="monitor the platforms of the config over Zenoh (`dkreason serve`)",
    )
    p.add_argument(
        "--ros2",
        action="store_true",
        help="monitor live ROS 2 robots over Zenoh (rmw_zenoh; --bridge: DDS robots "
        "through zenoh-bridge-ros2dds); no ROS install needed",
    )
    p.add_argument(
        "--domain",
        type=_domain,
        default=None,
        metavar="N",
        help="ros2: the ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID, else 0)",
    )
    p.add_argument(
        "--bridge",
        action="store_true",
        help="ros2: also take the publishers zenoh-bridge-ros2dds announces",
    )
    p.add_argument(
        "--bind",
        action="append",
        default=[],
        metavar="PLATFORM=NAMESPACE",
        help="ros2: topics of nodes in (or named under) NAMESPACE are PLATFORM's, "
        "by their names relative to it (repeatable)",
    )
    p.add_argument(
        "--sim-time",
        action="store_true",
        help="ros2: the stream clock is /clock (rosgraph_msgs/msg/Clock), as with use_sim_time",
    )
    p.add_argument(
        "--record",
        type=Path,
        metavar="OUT.mcap",
        help="ros2: write the relevant topics' messages and the verdicts (a JSON "
        "channel) to one MCAP file, which --source replays",
    )
    p.add_argument(
        "--publish-verdicts",
        action="store_true",
        help="live, ros2: put verdicts and violations on dkreason/verdicts/<formula "
        "id> (JSON); with --ros2 also on the ROS 2 topic /dkreason/verdicts",
    )
    network(p)
    p.add_argument(
        "--wait",
        type=_positive,
        default=10.0,
        help="live: seconds to wait for the local platform; ros2: after which the "
        "features no publisher feeds are named (default 10)",
    )
    p.add_argument("--until", type=_seconds, help="live: stop when the stream clock passes it")
    p.add_argument(
        "--trust",
        type=Path,
        metavar="KEYS",
        help="live: TOML of platform = Ed25519 public key (PEM); their samples "
        "must be signed (`serve --sign`)",
    )
    p.add_argument("--duration", type=_positive, help="live: stop after this many wall seconds")
    p.add_argument("--json", action="store_true", help="JSON lines: verdicts and violations")
    p.add_argument(
        "--plot",
        type=Path,
        help="draw features, verdicts and violations (.png, .svg or .pdf, as the name says)",
    )
    p.add_argument("--period", type=_seconds, help="state every PERIOD s (default: on change)")
    p.add_argument(
        "--deviation",
        type=_seconds,
        default=Fraction(0),
        help="allowed sample period deviation (default 0)",
    )
    p.add_argument(
        "--approximation",
        choices=("recent", "none"),
        default="recent",
        help="recent: the newest sample up to --max-age old; none: only a sample "
        "at the state's time (default recent)",
    )
    p.add_argument(
        "--max-age",
        type=_seconds_or_inf,
        default=Fraction(5),
        help="oldest sample used, in s (default 5; inf: any)",
    )
    p.add_argument(
        "--delay",
        type=_seconds,
        default=Fraction(1, 10),
        help="how long after a state's time its samples may still arrive (transport "
        "latency) before it is made (default 100ms)",
    )
    p.add_argument(
        "--start",
        type=_bound,
        metavar="[+]TIME",
        help="judge from this time on (s on the recording's clock; +TIME: after its first sample)",
    )
    p.add_argument(
        "--end",
        type=_bound,
        metavar="[+]TIME",
        help="ignore samples after this time (+TIME: after the first sample)",
    )
    p.add_argument("--max-delay", type=_seconds, help="largest allowed sample delay (s)")
    p.add_argument("--ordered", action="store_true", help="samples must come in valid-time order")
    p.add_argument("--unique", action="store_true", help="valid times must be unique")
    p.add_argument(
        "-f",
        "--formulas-file",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="formulas, one per line (# comments); repeatable",
    )
    p.add_argument("formulas", nargs="*", metavar="FORMULA")
    p.set_defaults(run=_monitor)

    p = sub.add_parser("serve", help="run a platform node: its knowledge and topics over Zenoh")
    config(p)
    network(p)
    p.add_argument(
        "--source",
        type=Path,
        help="replay this recording's topics of the platform (- : JSON lines on "
        "stdin, published as they come)",
    )
    definitions(p)
    p.add_argument(
        "--origin",
        type=_finite,
        help="wall time (Unix s) the replay starts at; nodes given the same one "
        "replay in step (default: now)",
    )
    p.add_argument("--speed", type=_positive, default=1.0, help="replay speed factor (default 1)")
    p.add_argument(
        "--heartbeat",
        type=_positive,
        default=0.02,
        help="seconds between clock messages (default 0.02)",
    )
    p.add_argument(
        "--sign",
        type=Path,
        metavar="KEY",
        help="sign every sample with this Ed25519 private key (PEM)",
    )
    p.set_defaults(run=_serve)

    p = sub.add_parser("explain", help="why each topic matched, or why one did not")
    config(p)
    p.add_argument("formula")
    p.add_argument("--feature", help='only this ground feature, e.g. "Altitude[uav2]"')
    p.add_argument("--topic", help="only this topic; explains why it was not chosen if not")
    p.add_argument("--format", choices=("text", "json", "dot"), default="text")
    p.set_defaults(run=_explain)

    p = sub.add_parser("specs", help="list, show, add or remove topic specifications")
    specs = p.add_subparsers(required=True, metavar="ACTION", parser_class=_Parser)
    for action, helptext in (
        ("list", "every topic specification"),
        ("show", "one topic specification"),
        ("add", "add an SSL_T topic specification (saved to the specs file)"),
        ("remove", "remove a topic specification (saved to the specs file)"),
    ):
        q = specs.add_parser(action, help=helptext)
        config(q)
        q.add_argument("--platform", help="platform (default: the local one; list: all)")
        if action == "show":
            q.add_argument("topic")
            q.add_argument("--xml", action="store_true", help="print the XML form")
        elif action == "add":
            q.add_argument("spec", help="e.g. 'topic t:Msg contains Speed(car1) = msg.spd'")
        elif action == "remove":
            q.add_argument("topic")
        q.set_defaults(run=_specs, action=action)

    p = sub.add_parser("info", help="what recordings hold, and which spec topics they bind")
    p.add_argument("--config", type=Path, help="TOML config: show which spec topics bind")
    p.add_argument("--json", action="store_true", help="one JSON document")
    definitions(p)
    p.add_argument("source", nargs="+", metavar="[PLATFORM=]PATH")
    p.set_defaults(run=_info, remap=[], clock="header")  # each recording's clock: describe()

    p = sub.add_parser("sort", help="the objects of a sort")
    config(p)
    p.add_argument("--platform")
    p.add_argument("sort")
    p.set_defaults(run=_sort)
    return parser


def _km(args: argparse.Namespace) -> KnowledgeManager:
    from .manager import KnowledgeManager

    return KnowledgeManager.from_config(args.config)


def _match(args: argparse.Namespace) -> int:
    import time

    start = time.perf_counter()
    km = _km(args)
    loaded = time.perf_counter()
    request = km.check_formula(args.formula)
    if args.stats:
        print(
            f"stats: load {(loaded - start) * 1e3:.1f} ms, match "
            f"{(time.perf_counter() - loaded) * 1e3:.1f} ms",
            file=sys.stderr,
        )
        for name, (kind, rows) in sorted(km.kb.engine.sizes().items()):
            print(f"stats: {kind:<5} {name:<20} {rows:>9}", file=sys.stderr)
    if args.json:
        print(json.dumps(request.to_json(), ensure_ascii=False))
    else:
        print(render_text(request))
    return 0


def _explain(args: argparse.Namespace) -> int:
    from . import explain

    result = _km(args).explain(args.formula, args.feature, args.topic)
    if args.format == "json":
        print(json.dumps(explain.to_json(result), ensure_ascii=False))
    elif args.format == "dot":
        print(explain.to_dot(result))
    else:
        print(explain.to_text(result))
    return 0


def _progress(args: argparse.Namespace) -> int:
    from .parse.formula import parse_formula
    from .progress import Progressor
    from .progress.state import feature_uses
    from .progress.statefile import read_states

    progressor = Progressor()
    trees = (
        [(f.text, f.tree) for f in _km(args).plan(args.formulas).formulas]
        if args.config
        else [(f, parse_formula(f)) for f in args.formulas]
    )
    for text, tree in trees:
        progressor.add(text, tree if args.config else None)
    used = {k: use for k, (use, _) in feature_uses(trees).items()}
    verdicts = []

    def emit(batch: list[Any]) -> None:
        for v in batch:
            verdicts.append(v)
            if args.json:
                print(json.dumps(v.to_json(), ensure_ascii=False, default=str), flush=True)
            else:
                value = {True: "true", False: "FALSE", None: "unknown"}[v.verdict]
                when = "at end" if v.at_end else "at"
                print(
                    f"{when} {v.time}: {value}  {v.formula}"
                    + (f"\n    {v.witness}" if v.witness else ""),
                    flush=True,
                )

    for time, values in read_states(args.states, used):
        emit(progressor.step(time, values))
    emit(progressor.finish())
    return exit_status([v.verdict for v in verdicts])


def _seconds(text: str) -> Fraction:
    """A duration as formulas write it: seconds, or a number with ms, s, min or h."""
    from .inputs.numbers import exact
    from .parse.formula import UNITS

    number, unit = re.fullmatch(r"\s*(.*?)\s*(ms|s|min|h)?\s*", text).groups()  # type: ignore[union-attr]
    try:
        value = exact(number, "seconds") * UNITS[unit or "s"]
    except DkError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a duration (like 5, 0.1, 500ms, 2min)"
        ) from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative: {text}")
    return value


def _bound(text: str) -> tuple[Fraction, bool]:
    """A start or end time: seconds on the recording's clock, or +SECONDS after its start."""
    return (_seconds(text[1:]), True) if text.startswith("+") else (_seconds(text), False)


def _finite(text: str) -> float:
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text}")
    return value


def _positive(text: str) -> float:
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive: {text}")
    return value


def _seconds_or_inf(text: str) -> Fraction | None:
    return None if text in ("inf", "oo") else _seconds(text)


def _logging() -> None:
    import logging

    logging.basicConfig(stream=sys.stderr, level=logging.INFO, format="%(name)s: %(message)s")


def _session(args: argparse.Namespace) -> Any:
    from .live.wire import open_session

    return open_session(args.connect, args.listen, args.zenoh_config)


def _on_signals(handler: Any) -> None:
    import signal

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def _interrupt(*_: object) -> None:
    raise KeyboardInterrupt


def _serve(args: argparse.Namespace) -> int:
    from .live import wire
    from .live.serve import PlatformNode
    from .stream.sources import open_source

    _logging()
    km = _km(args)
    source = open_source(args.source, args.msg, args.typestore) if args.source is not None else None
    records = getattr(source, "records", None)
    if source is not None and records is None:
        raise DkError(f"{source.name}: a damaged recording cannot be replayed live")
    sign = wire.signer(args.sign) if args.sign is not None else None
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


def _monitor(args: argparse.Namespace) -> int:
    from .monitor import Monitor
    from .plot import plot
    from .progress import Verdict
    from .stream.processor import StreamPolicy

    relative = {bound[1] for bound in (args.start, args.end) if bound is not None}
    if len(relative) > 1:
        raise DkError("--start and --end must be both relative (+SECONDS) or both absolute")
    policy = StreamPolicy(
        sample_period=args.period,
        sample_period_deviation=args.deviation,
        approximation=args.approximation,
        max_age=args.max_age,
        delay_before_approximation=args.delay,
        start_time=None if args.start is None else args.start[0],
        end_time=None if args.end is None else args.end[0],
        max_delay=args.max_delay,
        ordered_on_valid_time=args.ordered,
        unique_valid_time=args.unique,
        span_from_first=relative == {True},
    )
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
            ("--record", args.record),
            ("--domain", args.domain),
        )
        if given not in (False, [], None)
    ]
    if ros2_only and not args.ros2:
        raise DkError(f"{ros2_only[0]} is for --ros2")
    if args.publish_verdicts and not (args.live or args.ros2):
        raise DkError("--publish-verdicts is for --live or --ros2")
    if args.ros2:
        return _monitor_ros2(args, policy)
    if args.live:
        return _monitor_live(args, policy)
    if not args.source:
        raise DkError("monitor needs --source RECORDING, or --live")
    km = _km(args)
    monitor = Monitor(
        km.plan(_formulas(args)), km.request, policy, keep_states=args.plot is not None
    )
    source = _recordings(args, set(km.platforms))
    try:
        processor = monitor.start(source)
    except BaseException:
        source.close()
        raise
    for topic, features in processor.absent.items():
        print(
            f"warning: {topic} (for {', '.join(dict.fromkeys(features))}) is in no recording",
            file=sys.stderr,
        )
    note = getattr(source, "note", None)
    if note:
        print(f"note: {note}", file=sys.stderr)
    if not args.json:
        print(render_text(monitor.request), flush=True)
    events: list[Any] = []
    error = None
    with _progress_bar(source, monitor, enabled=not args.json) as tick:
        try:
            for event in monitor.run(source, tick):
                events.append(event)
                _print_event(event, args.json, processor.first)
        except DkError as exc:
            error = exc
    verdicts = [e for e in events if isinstance(e, Verdict)]
    if not args.json:
        _summary(verdicts, len(events) - len(verdicts))
    if args.plot is not None and monitor.states:
        plot(monitor, events, args.plot)
        if not args.json:
            print(f"plot written to {args.plot}")
    if error is not None:
        raise error
    return exit_status([v.verdict for v in verdicts])


def _monitor_live(args: argparse.Namespace, policy: Any) -> int:
    from .live.monitor import LiveMonitor
    from .live.wire import trusted_keys

    if args.source or args.plot is not None:
        raise DkError("--live takes no --source and no --plot")
    _logging()
    trust = trusted_keys(args.trust) if args.trust is not None else None
    formulas = _formulas(args)
    session = _session(args)
    try:
        monitor = LiveMonitor(args.config, formulas, policy, session, args.wait, trust=trust)
        _on_signals(lambda *_: monitor.stop.set())
        return _report(
            args,
            monitor.run(args.until, args.duration),
            lambda: getattr(monitor, "processor", None),
            session,
            [f.text for f in monitor.formulas],
            ros2=False,
            reads=lambda key: _reading(monitor.monitor, key),
        )
    finally:
        session.close()


def _monitor_ros2(args: argparse.Namespace, policy: Any) -> int:
    import os

    from .live.record import Recorder
    from .live.ros2 import Ros2Monitor
    from .stream.typestore import load_typestore, msg_types

    if args.source or args.plot is not None or args.live:
        raise DkError("--ros2 takes no --source, --plot or --live")
    _logging()
    bind = {}
    for given in args.bind:
        platform, sep, namespace = given.partition("=")
        if not sep or not namespace.startswith("/"):
            raise DkError(f"--bind {given!r}: expected PLATFORM=/NAMESPACE")
        bind[platform] = namespace
    try:
        domain = (
            args.domain
            if args.domain is not None
            else _domain(os.environ.get("ROS_DOMAIN_ID", "0") or "0")
        )
    except argparse.ArgumentTypeError as exc:
        raise DkError(f"$ROS_DOMAIN_ID: {exc}") from None
    km = _km(args)
    unknown = sorted(set(bind) - set(km.platforms))
    if unknown:
        raise DkError(
            f"--bind {unknown[0]}: not a platform of the config (platforms: "
            f"{', '.join(sorted(km.platforms))})"
        )
    store = load_typestore(msg_types(args.msg), False, args.typestore or "ros2_jazzy")
    formulas = _formulas(args)
    recorder = Recorder(args.record, store) if args.record is not None else None
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
            remap=_remaps(args),
            sim_time=args.sim_time,
            recorder=recorder,
        )
        recorder = None  # the monitor closes it
        _on_signals(lambda *_: monitor.stop.set())
        return _report(
            args,
            monitor.run(args.until, args.duration, args.wait),
            lambda: monitor.processor,
            session,
            [f.text for f in monitor.monitor.plan.formulas],
            ros2=True,
            domain=domain,
            labelled=lambda: monitor.labelled,
            reads=lambda key: _reading(monitor.monitor, key),
        )
    finally:
        if recorder is not None:
            recorder.close()
        session.close()


def _reading(monitor: Any, key: Any) -> list[str]:
    """The formulas (as written) of a running Monitor that read a feature."""
    return [f.text for f in monitor.plan.formulas if key in f.keys]


def _report(
    args: argparse.Namespace,
    events: Any,
    processor: Any,
    session: Any,
    formulas: list[str],
    ros2: bool,
    domain: int = 0,
    labelled: Any = None,
    reads: Any = None,
) -> int:
    """A live run's events printed (and published with --publish-verdicts) as they come."""
    from .live.monitor import Change
    from .live.ros2node import Announcer
    from .progress import Verdict

    announce = (
        Announcer(session, formulas, ros2, domain, labelled, reads)
        if args.publish_verdicts
        else None
    )
    verdicts, violations = [], 0
    try:
        for event in events:
            if announce is not None:
                announce(event)
            if isinstance(event, Change):
                print(
                    json.dumps(event.to_json(), ensure_ascii=False) if args.json else str(event),
                    flush=True,
                )
                continue
            if isinstance(event, Verdict):
                verdicts.append(event)
            else:
                violations += 1
            shown = processor()
            _print_event(event, args.json, shown.first if shown else None)
    finally:
        if announce is not None:
            announce.close()
    if not args.json:
        _summary(verdicts, violations)
    return exit_status([v.verdict for v in verdicts])


def _domain(text: str) -> int:
    """A ROS_DOMAIN_ID: 0 to 232 (an argparse type, so a ValueError is its one-line error)."""
    if not text.isdigit() or int(text) > 232:
        raise argparse.ArgumentTypeError(f"ROS domain id {text!r}: expected 0 to 232")
    return int(text)


def _formulas(args: argparse.Namespace) -> list[str]:
    """The formulas given, then those of each -f file (one a line, # comments)."""
    from .inputs.files import read_text

    out = list(args.formulas)
    for path in args.formulas_file:
        out += [
            line.strip()
            for line in read_text(path).splitlines()
            if line.strip() and not line.strip().startswith("#")
        ]
    if not out:
        raise DkError("no formula given (as arguments or with -f FILE)")
    return out


def _recordings(args: argparse.Namespace, platforms: set[str]) -> Any:
    """--source [PLATFORM=]PATH (repeatable) and --remap FROM:=TO, as one source."""
    from .stream.binding import Recording, Recordings
    from .stream.sources import open_source

    remap = _remaps(args)
    parts = []
    try:
        for given in args.source:
            platform, sep, path = given.partition("=")
            if sep and platform not in platforms and not Path(given).exists():
                raise DkError(
                    f"--source {given}: {platform!r} is not a platform of the config "
                    f"(platforms: {', '.join(sorted(platforms))})"
                )
            if not sep or platform not in platforms:
                platform, path = "", given
            parts.append(
                Recording(open_source(Path(path), args.msg, args.typestore), platform or None)
            )
        return Recordings(parts, remap, args.clock)
    except BaseException:
        for r in parts:
            r.source.close()
        raise


def _remaps(args: argparse.Namespace) -> dict[str, str]:
    """--remap FROM:=TO (repeatable)."""
    remap = {}
    for rule in args.remap:
        old, sep, new = rule.partition(":=")
        if not sep or not old or not new:
            raise DkError(f"--remap {rule!r}: expected FROM:=TO")
        remap[old] = new
    return remap


def _info(args: argparse.Namespace) -> int:
    from .stream.info import bindings, describe, render

    km = _km(args) if args.config else None
    recordings = _recordings(args, set(km.platforms) if km else set())
    try:
        infos = [describe(r) for r in recordings.parts]
        binds = bindings(km.kb, recordings) if km else None
    finally:
        recordings.close()
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
        print(render(infos, binds))
    return 0


def _print_event(event: Any, as_json: bool, origin: int | None = None) -> None:
    """A verdict or violation; with the recording's first time (ns), times also as `t+…`
    since then (and, on an epoch clock, as ISO 8601 UTC)."""
    from .progress import Verdict

    out = event.to_json()
    if as_json:
        if origin is not None and out.get("time") is not None:
            out["t"] = _since(out["time"], origin)
        print(json.dumps(out, ensure_ascii=False, default=str), flush=True)
        return
    when = _when(out.get("time"), origin)
    if isinstance(event, Verdict):
        value = {True: "held", False: "VIOLATED", None: "unknown"}[event.verdict]
        print(
            f"{'at end' if event.at_end else f'at {when}'}: {value}  {event.formula}"
            + (f"\n    {event.witness}" if event.witness else ""),
            flush=True,
        )
    else:
        print(
            f"violation at {when}: {event.constraint} on {event.feature} ({event.topic}): "
            f"{event.detail}",
            flush=True,
        )


def _when(time: Any, origin: int | None) -> str:
    if time is None or not origin:  # a clock that starts at 0 needs no second reading
        return f"{time} s"
    import datetime

    stamp = f"{time} s"
    if time > 10**9:  # an epoch clock: the date says more than a ten-digit number
        stamp = (
            datetime.datetime.fromtimestamp(time, datetime.UTC)
            .isoformat(timespec="milliseconds")
            .replace("+00:00", "Z")
        )
    return f"t+{_since(time, origin)} s ({stamp})"


def _since(time: float, origin: int) -> float:
    """Seconds from `origin` (ns) to `time` (s, as printed), exact to the nanosecond."""
    from decimal import Decimal

    return float(Decimal(repr(time)) - Decimal(origin) / 10**9)


def _summary(verdicts: list[Any], violations: int) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title="dkreason monitor", title_justify="left")
    for column in ("formula", "verdict", "time (s)", "at end"):
        table.add_column(column)
    for v in verdicts:
        verdict = {True: "held", False: "violated", None: "unknown"}[v.verdict]
        table.add_row(escape(v.formula), verdict, str(v.time), "yes" if v.at_end else "no")
    console = Console(width=120)
    console.print(table)
    console.print(f"{violations} stream constraint violation(s)")


class _progress_bar:
    """A progress bar on stderr while a long file is read (only on a terminal)."""

    def __init__(self, source: Any, monitor: Any, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.total = source.count(None) if self.enabled else None
        self.bar: Any = None

    def __enter__(self) -> Any:
        if not self.enabled:
            return None
        from rich.progress import Progress

        self.bar = Progress(transient=True)
        self.bar.start()
        task = self.bar.add_task("reading", total=self.total)
        return lambda n: self.bar.update(task, completed=n)

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()


def exit_status(verdicts: list[bool | None]) -> int:
    """0: every formula held; 1: one was violated; 3: none violated, one left unknown."""
    if False in verdicts:
        return 1
    return 0 if all(verdicts) else 3


def render_text(request: StreamRequest) -> str:
    """Thesis listings 6.2–6.4 and 6.8–6.10, plus where remote topics come from."""
    lines = []
    for f in request.features:
        lines += [
            f"Feature: {f.feature.key}",
            "Topics to merge:" if f.topics else "Topics to merge: none",
        ]
        for t in f.topics:
            ids = "".join(f"Id: {k} = {v}, " for k, v in t.filter)
            where = (
                ""
                if t.platform == request.local
                else f" (platform {t.platform}, as {t.as_feature}[{', '.join(t.as_args)}])"
            )
            lines.append(
                f"  Topic: {t.topic}{where}, Message type: {t.msgtype}, {ids}Field: {t.field}"
            )
    lines += [f"Warning: {w}" for w in request.warnings]
    return "\n".join(lines)


def _specs(args: argparse.Namespace) -> int:
    from .parse.sslt import format_spec, format_xml_topic

    km = _km(args)
    if args.action == "list":
        for platform in [args.platform] if args.platform else km.platforms:
            for spec in km.list_topic_specifications(platform):
                print(f"{platform}: {format_spec(spec)}")
    elif args.action == "show":
        spec = km.get_topic_specification(args.topic, args.platform)
        print(format_xml_topic(spec, indent="") if args.xml else format_spec(spec))
    elif args.action == "add":
        spec = km.add_topic(args.spec, args.platform)
        print(f"added {spec.name} to {args.platform or km.local}")
    else:
        km.remove_topic(args.topic, args.platform)
        print(f"removed {args.topic} from {args.platform or km.local}")
    return 0


def _sort(args: argparse.Namespace) -> int:
    for name in _km(args).list_sort(args.sort, args.platform):
        print(name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
