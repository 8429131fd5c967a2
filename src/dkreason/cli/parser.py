"""The command line, declared: every command and option, grouped by mode.  A command names
the function that runs it (`module:function` in cli/), imported only when it runs, so
`dkreason --help` loads no engine."""

from __future__ import annotations

import argparse
from fractions import Fraction
from pathlib import Path
from typing import Any, NoReturn

from ..live.wire import LIMITS
from ..results import DEFAULT_DB, VERDICTS
from ..stream.policy import APPROXIMATIONS, DEFAULT, END_OF_DATA
from . import args as a

EXIT_STATUS = (
    "exit status: 0 every formula held, 1 one was violated (or, with --fail-on-constraint, "
    "a stream constraint was), 2 bad input (one line on stderr), 3 one stayed undecided"
)


class _Version(argparse.Action):
    """--version, reading the installed version only when asked (importlib.metadata costs
    more than the rest of `dkreason --help`)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: Any) -> NoReturn:
        from importlib.metadata import version

        print(f"dkreason {version('dkreason')}")
        parser.exit(0)


def build(description: str | None) -> a.Parser:
    parser = a.Parser(prog="dkreason", description=description)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(required=True, metavar="COMMAND", parser_class=a.Parser)
    _match(sub)
    _progress(sub)
    _monitor(sub)
    _serve(sub)
    _explain(sub)
    _specs(sub)
    _info(sub)
    _plot(sub)
    _init(sub)
    _sort(sub)
    _batch(sub)
    _results(sub)
    _rules(sub)
    _query(sub)
    _test(sub)
    _completion(sub)
    return parser


def _match(sub: a.Sub) -> None:
    p = sub.add_parser("match", help="the topics each feature of a formula is read from")
    a.config(p)
    p.add_argument("--json", action="store_true", help="print the stream request as JSON")
    p.add_argument(
        "--stats",
        action="store_true",
        help="on stderr: load and match times, and the rows of every stored "
        "relation (told facts and materialized views)",
    )
    _max_delay(p)
    _best_source(p)
    p.add_argument("formula")
    p.set_defaults(run="knowledge:match")


def _progress(sub: a.Sub) -> None:
    p = sub.add_parser("progress", help="verdicts of formulas over a JSON-lines state file")
    p.add_argument(
        "--states",
        required=True,
        type=Path,
        help='JSON lines: {"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5}}',
    )
    p.add_argument("--config", type=Path, help="TOML config: quantifiers range over its objects")
    p.add_argument("--json", action="store_true", help="one JSON line per formula")
    _robustness(p)
    _end_of_data(p)
    p.add_argument("formulas", nargs="+", metavar="FORMULA")
    p.set_defaults(run="monitoring:progress")


def _robustness(p: Any) -> None:
    p.add_argument(
        "--robustness",
        action="store_true",
        help="with each verdict, by how much it held or failed (STL space robustness), its "
        "critical atom and where that atom's values came from",
    )


def _monitor(sub: a.Sub) -> None:
    p = sub.add_parser(
        "monitor",
        help="verdicts of formulas over a robot recording, or live",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"{EXIT_STATUS}\n\n"
        "example:\n  dkreason monitor --config examples/federation.toml --source "
        "examples/traffic/recording --delay 100ms \\\n    'forall c in Car: always "
        "(Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)'",
    )
    a.config(p)
    a.formulas_file(p)
    p.add_argument("formulas", nargs="*", metavar="FORMULA")
    p.set_defaults(run="monitoring:monitor")

    p.add_argument(
        "--source",
        action="append",
        default=[],
        metavar="[PLATFORM=]PATH",
        help="ROS 1 .bag, ROS 2 bag folder or .mcap/.db3 file, or .jsonl messages; "
        "several (--source A B, or repeated) are merged by record time; PLATFORM= "
        "binds a recording's topics to that platform's specs only",
    )
    out = p.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="JSON lines: verdicts and violations")
    _robustness(out)
    out.add_argument(
        "--plot",
        type=Path,
        help="draw features, verdicts and violations (.png, .svg or .pdf, as the name says)",
    )
    out.add_argument(
        "--fail-on-constraint",
        action="store_true",
        help="exit 1 when a stream constraint was violated, as when a formula was",
    )
    out.add_argument(
        "--record",
        type=Path,
        metavar="OUT.mcap",
        help="recordings and --ros2: write the relevant topics' messages (byte for byte) and "
        "the verdicts (foxglove.Log on /dkreason/log, JSON on /dkreason/events) to one MCAP "
        "file, which Foxglove opens and --source replays; an existing file is refused",
    )
    out.add_argument(
        "--force", action="store_true", help="--record and --clips overwrite existing files"
    )
    out.add_argument(
        "--clips",
        type=Path,
        metavar="DIR",
        help="recordings: one MCAP file per violation in DIR, the relevant topics from "
        "--clip-margin before its witness window to --clip-margin after it",
    )
    out.add_argument(
        "--foxglove",
        metavar="[HOST:]PORT",
        help="serve the run to Foxglove (open ws://localhost:PORT): each feature's values on "
        "/dkreason/feature/NAME/ARG, the verdicts as foxglove.Log on /dkreason/log; a "
        "replay starts when Foxglove subscribes to a topic (HOST: default 127.0.0.1)",
    )
    out.add_argument(
        "--speed",
        type=a.speed,
        metavar="X",
        help="recordings: replay at X times the recorded pace (1: real time, 0: as fast as "
        "it reads; default 1 with --foxglove, else 0)",
    )
    out.add_argument(
        "--clip-margin",
        type=a.seconds,
        default=Fraction(2),
        metavar="SECONDS",
        help="--clips: seconds kept before and after a witness window (default 2)",
    )

    _recordings(p)
    _policy(p)

    live = p.add_argument_group("live (--live: dkreason serve nodes; --ros2: ROS 2 robots)")
    live.add_argument(
        "--live",
        action="store_true",
        help="monitor the platforms of the config over Zenoh (`dkreason serve`)",
    )
    live.add_argument(
        "--ros2",
        action="store_true",
        help="monitor live ROS 2 robots over Zenoh (rmw_zenoh; --bridge: DDS robots "
        "through zenoh-bridge-ros2dds); no ROS install needed",
    )
    a.network(live)
    live.add_argument(
        "--publish-verdicts",
        action="store_true",
        help="live, ros2: put verdicts and violations on dkreason/verdicts/<formula "
        "id> (JSON); with --ros2 also on the ROS 2 topic /dkreason/verdicts",
    )
    live.add_argument(
        "--wait",
        type=a.positive,
        default=10.0,
        help="live: seconds to wait for the local platform; ros2: after which the "
        "features no publisher feeds are named (default 10)",
    )
    live.add_argument("--until", type=a.seconds, help="live: stop when the stream clock passes it")
    live.add_argument("--duration", type=a.positive, help="live: stop after this many wall seconds")
    live.add_argument(
        "--trust",
        type=Path,
        metavar="KEYS",
        help="live: TOML of platform = Ed25519 public key (PEM); their samples "
        "must be signed (`serve --sign`)",
    )
    live.add_argument(
        "--max-peer-topics",
        type=a.whole,
        default=LIMITS.topics,
        metavar="N",
        help=f"live: a platform whose specs hold more topics is refused "
        f"(default {LIMITS.topics:,})",
    )
    live.add_argument(
        "--max-peer-objects",
        type=a.whole,
        default=LIMITS.objects,
        metavar="N",
        help=f"live: a platform whose knowledge holds more object memberships is refused "
        f"(default {LIMITS.objects:,})",
    )
    live.add_argument(
        "--domain",
        type=a.domain,
        default=None,
        metavar="N",
        help="ros2: the ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID, else 0)",
    )
    live.add_argument(
        "--bridge",
        action="store_true",
        help="ros2: also take the publishers zenoh-bridge-ros2dds announces",
    )
    live.add_argument(
        "--bind",
        action="append",
        default=[],
        metavar="PLATFORM=NAMESPACE",
        help="ros2: topics of nodes in (or named under) NAMESPACE are PLATFORM's, "
        "by their names relative to it (repeatable)",
    )
    live.add_argument(
        "--sim-time",
        action="store_true",
        help="ros2: the stream clock is /clock (rosgraph_msgs/msg/Clock), as with use_sim_time",
    )


def _recordings(p: argparse.ArgumentParser) -> None:
    """How recordings are read, for monitor and batch alike."""
    rec = p.add_argument_group("recordings")
    rec.add_argument(
        "--remap",
        action="append",
        default=[],
        metavar="FROM:=TO",
        help="read recording topic FROM as TO (repeatable)",
    )
    rec.add_argument(
        "--clock",
        choices=("auto", "header", "record"),
        default="auto",
        help="valid time from header.stamp or the record time; auto: the stamps, "
        "unless they run on another clock (simulated time), said in one line "
        "(default auto)",
    )
    a.definitions(rec)


def _policy(p: argparse.ArgumentParser) -> None:
    """The stream policy, for monitor and batch alike."""
    pol = p.add_argument_group("stream policy (the API's StreamPolicy, same defaults)")
    pol.add_argument("--period", type=a.seconds, help="state every PERIOD s (default: on change)")
    pol.add_argument(
        "--deviation",
        type=a.seconds,
        help=f"allowed sample period deviation (default {DEFAULT.sample_period_deviation})",
    )
    pol.add_argument(
        "--approximation",
        choices=APPROXIMATIONS,
        help="recent: the newest sample up to --max-age old; none: only a sample "
        f"at the state's time (default {DEFAULT.approximation})",
    )
    pol.add_argument(
        "--max-age",
        type=a.seconds_or_inf,
        help=f"oldest sample used, in s (default {DEFAULT.max_age}; inf: any)",
    )
    pol.add_argument(
        "--delay",
        type=a.seconds,
        help="how long after a state's time its samples may still arrive (transport "
        f"latency) before it is made (default {DEFAULT.delay_before_approximation * 1000}ms)",
    )
    pol.add_argument(
        "--start",
        type=a.bound,
        metavar="TIME",
        help="judge from this time on: +SECONDS after the recording's start (where t+ "
        "counts from), s on its clock, or ISO 8601 (2014-03-31T19:24:50Z)",
    )
    pol.add_argument(
        "--end",
        type=a.bound,
        metavar="TIME",
        help="judge up to this time, the end of the data (as --start); later messages are not read",
    )
    _max_delay(pol)
    _best_source(pol)
    pol.add_argument(
        "--set-aside-after",
        type=a.count,
        metavar="N",
        help="set aside a topic declaring a rate once its samples stop for N declared periods "
        "(its features read from the other relevant topics until it sends again; "
        f"default {DEFAULT.set_aside_after}, 0: never)",
    )
    pol.add_argument("--ordered", action="store_true", help="samples must come in valid-time order")
    pol.add_argument("--unique", action="store_true", help="valid times must be unique")
    _end_of_data(pol)


def _max_delay(p: Any) -> None:
    p.add_argument(
        "--max-delay",
        type=a.seconds,
        help="largest allowed sample delay (s); a topic declaring a larger delay is not read",
    )


def _best_source(p: Any) -> None:
    p.add_argument(
        "--best-source",
        action="store_true",
        help="read each feature from its best-ranked topic only (by declared rate and delay), "
        "not from the merge of every relevant topic",
    )


def _end_of_data(p: Any) -> None:
    p.add_argument(
        "--end-of-data",
        choices=END_OF_DATA,
        help="open: a bounded window (eventually[0, 5]) reaching past the end of the data "
        "leaves its formula undecided, saying what is pending; finite: it closes there, as on "
        f"a finite trace (default {DEFAULT.end_of_data})",
    )


def _batch(sub: a.Sub) -> None:
    p = sub.add_parser(
        "batch",
        help="monitor many runs (recordings, folders, @LIST files) into a results database",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="exit status: 0 every formula held on every run, 1 one was violated on some "
        "run (or, with --fail-on-constraint, a stream constraint was), 3 a run was undecided "
        "or failed, 2 bad input to the batch\n\nexample:\n"
        "  dkreason batch --config examples/federation.toml --formula "
        "'always (Speed[car1] < 90)' runs/",
    )
    a.config(p)
    a.formulas_file(p)
    p.add_argument(
        "--formula",
        dest="formulas",
        action="append",
        default=[],
        metavar="TEXT",
        help="a formula (repeatable)",
    )
    p.add_argument(
        "sources",
        nargs="+",
        metavar="SOURCE",
        help="a recording, a folder searched for recordings (a ROS 2 bag folder is one run), "
        "or @LIST: a file of runs, one a line ([PLATFORM=]PATH items)",
    )
    run = p.add_argument_group("where and how")
    run.add_argument(
        "--jobs", type=a.whole, help="local worker processes (default: the machine's cores)"
    )
    run.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="a running Dask cluster's scheduler (its workers must have dkreason and see the "
        "recordings' paths)",
    )
    run.add_argument(
        "--db",
        type=Path,
        default=DEFAULT_DB,
        help=f"the results database (DuckDB; default {DEFAULT_DB})",
    )
    run.add_argument(
        "--resume",
        action="store_true",
        help="continue the latest batch with the same config, formulas and options",
    )
    run.add_argument(
        "--timeout", type=a.positive, help="seconds of monitoring a run may take on its worker"
    )
    run.add_argument("--json", action="store_true", help="each row as a JSON line")
    run.add_argument(
        "--fail-on-constraint",
        action="store_true",
        help="exit 1 when a stream constraint was violated on some run, as when a formula was",
    )
    _recordings(p)
    _policy(p)
    p.set_defaults(run="fleet:batch")


def _results(sub: a.Sub) -> None:
    p = sub.add_parser("results", help="what batches found: a summary, rows, or a diff")
    p.add_argument("--db", type=Path, default=DEFAULT_DB, help=f"default {DEFAULT_DB}")
    p.add_argument("--batch", metavar="ID", help="default: the latest batch")
    p.add_argument("--formula", metavar="TEXT", help="only this formula")
    p.add_argument("--verdict", choices=VERDICTS, help="only rows with this verdict")
    p.add_argument("--json", action="store_true", help="the rows as JSON lines")
    p.add_argument("--parquet", type=Path, metavar="OUT", help="the batch's rows to a Parquet file")
    p.add_argument(
        "--diff",
        nargs=2,
        metavar=("BATCH_A", "BATCH_B"),
        help="the (run, formula) pairs whose verdict changed from A to B",
    )
    p.set_defaults(run="fleet:results")


def _serve(sub: a.Sub) -> None:
    p = sub.add_parser("serve", help="run a platform node: its knowledge and topics over Zenoh")
    a.config(p)
    a.network(p)
    p.add_argument(
        "--source",
        type=Path,
        help="replay this recording's topics of the platform (- : JSON lines on "
        "stdin, published as they come)",
    )
    a.definitions(p)
    p.add_argument(
        "--origin",
        type=a.wall_time,
        help="wall time (Unix s) the replay starts at; nodes given the same one "
        "replay in step (default: now)",
    )
    p.add_argument("--speed", type=a.positive, default=1.0, help="replay speed factor (default 1)")
    p.add_argument(
        "--heartbeat",
        type=a.positive,
        default=0.02,
        help="seconds between clock messages (default 0.02)",
    )
    p.add_argument(
        "--sign",
        type=Path,
        metavar="KEY",
        help="sign every sample with this Ed25519 private key (PEM)",
    )
    p.set_defaults(run="live:serve")


def _explain(sub: a.Sub) -> None:
    p = sub.add_parser("explain", help="why each topic matched, or why one did not")
    a.config(p)
    p.add_argument("formula")
    p.add_argument("--feature", help='only this ground feature, e.g. "Altitude[uav2]"')
    p.add_argument("--topic", help="only this topic; explains why it was not chosen if not")
    _max_delay(p)
    _best_source(p)
    p.add_argument("--format", choices=("text", "json", "dot"), default="text")
    p.add_argument(
        "--proof",
        action="store_true",
        help="text: also each proof tree and why-not trace (a shared subtree once)",
    )
    p.add_argument(
        "--depth", type=a.whole, metavar="N", help="text: proof trees to depth N (implies --proof)"
    )
    p.set_defaults(run="knowledge:explain")


def _specs(sub: a.Sub) -> None:
    p = sub.add_parser("specs", help="list, show, add or remove topic specifications")
    actions = p.add_subparsers(required=True, metavar="ACTION", parser_class=a.Parser)
    for action, helptext in (
        ("list", "every topic specification"),
        ("show", "one topic specification"),
        ("add", "add an SSL_T topic specification (saved to the specs file)"),
        ("remove", "remove a topic specification (saved to the specs file)"),
    ):
        q = actions.add_parser(action, help=helptext)
        a.config(q)
        q.add_argument("--platform", help="platform (default: the local one; list: all)")
        if action == "show":
            q.add_argument("topic")
            q.add_argument("--xml", action="store_true", help="print the XML form")
        elif action == "add":
            q.add_argument("spec", help="e.g. 'topic t:Msg contains Speed(car1) = msg.spd'")
        elif action == "remove":
            q.add_argument("topic")
        q.set_defaults(run="knowledge:specs", action=action)


def _info(sub: a.Sub) -> None:
    p = sub.add_parser(
        "info",
        help="what recordings hold, and which spec topics they bind; with a config alone, "
        "each platform's features, their signatures and where each came from",
    )
    p.add_argument("--config", type=Path, help="TOML config: show which spec topics bind")
    p.add_argument("--json", action="store_true", help="one JSON document")
    p.add_argument(
        "--fields",
        action="store_true",
        help="each topic's field paths a spec can read (msg.pose.position.z), with their "
        "types; array elements as msg.ranges[i] (any length) or msg.covariance[0..35]",
    )
    p.add_argument(
        "--timing",
        action="store_true",
        help="each topic's observed rate (median and 5th percentile of the inter-arrival "
        "rate) and delay (header stamp to record time: median and 95th percentile); reads "
        "every message",
    )
    a.definitions(p)
    p.add_argument(
        "source",
        nargs="*",
        metavar="[PLATFORM=]PATH",
        help="a recording, or a folder of recordings (each described); none: with --config, "
        "the platforms' features",
    )
    p.set_defaults(run="monitoring:info")


def _plot(sub: a.Sub) -> None:
    p = sub.add_parser(
        "plot",
        help="features' values over time from a recording (to pick a threshold)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  dkreason plot --config examples/single.toml --source run.mcap "
        "-o speeds.png 'Speed[car1]' 'Speed[car2]'",
    )
    a.config(p)
    p.add_argument(
        "--source",
        action="append",
        required=True,
        metavar="[PLATFORM=]PATH",
        help="the recording(s), as monitor takes them",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        metavar="OUT",
        help="the image: .png, .svg or .pdf, as the name says",
    )
    _recordings(p)
    p.add_argument("features", nargs="+", metavar="FEATURE", help="a ground feature: Speed[car1]")
    p.set_defaults(run="monitoring:plot")


def _init(sub: a.Sub) -> None:
    p = sub.add_parser(
        "init",
        help="a starter model from a recording: ontology, specs and config, a feature per field",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  dkreason init --source run.mcap --robot rover --topics /odom /battery "
        "model/\n  dkreason monitor --config model/rover.toml --source run.mcap "
        "'always (BatteryPercentage[rover] > 0.2)'",
    )
    p.add_argument(
        "--source",
        action="append",
        required=True,
        metavar="PATH",
        help="a recording whose topics and fields the model describes (several: --source A B)",
    )
    p.add_argument(
        "--robot",
        default="robot",
        help="the robot's name: its object, platform and files (default robot)",
    )
    p.add_argument(
        "--topics",
        action="append",
        default=[],
        metavar="TOPIC",
        help="only these topics, as info names them (--topics /odom /battery; default: all)",
    )
    a.definitions(p)
    p.add_argument("folder", type=Path, metavar="DIR", help="where ROBOT.ttl, .sslt, .toml go")
    p.set_defaults(run="knowledge:init")


def _sort(sub: a.Sub) -> None:
    p = sub.add_parser("sort", help="the objects of a sort")
    a.config(p)
    p.add_argument("--platform")
    p.add_argument("sort")
    p.set_defaults(run="knowledge:sort")


def _rules(sub: a.Sub) -> None:
    p = sub.add_parser("rules", help="check a matching policy's rule files")
    actions = p.add_subparsers(required=True, metavar="ACTION", parser_class=a.Parser)
    q = actions.add_parser(
        "check",
        help="every error and warning of a policy, one line each (exit 2 on an error)",
    )
    a.config(q, required=False)
    q.add_argument(
        "--replace",
        action="store_true",
        help="without --config: the files are the whole policy, not additions to the shipped one",
    )
    q.add_argument(
        "files",
        nargs="*",
        type=Path,
        metavar="FILE",
        help="rule files besides the config's policy (none: the config's, or the shipped one)",
    )
    q.set_defaults(run="rules:check")


def _query(sub: a.Sub) -> None:
    p = sub.add_parser("query", help="ask the knowledge base a question in the rules' language")
    a.config(p)
    p.add_argument("--json", action="store_true", help="the answer's rows as JSON")
    p.add_argument(
        "--relations",
        action="store_true",
        help="every relation: its columns, kind and rows",
    )
    p.add_argument(
        "question",
        nargs="?",
        metavar="QUERY",
        help="e.g. \"same_as(P, O, 'uav2')\" or \"relevant_topic(F, ('uav1',), T, Filter)\"",
    )
    p.set_defaults(run="rules:query")


def _test(sub: a.Sub) -> None:
    p = sub.add_parser(
        "test",
        help="run the golden test cases of a folder (exit 1 with a diff on a difference)",
    )
    p.add_argument("folder", type=Path, metavar="DIR", help="searched for *.json test cases")
    p.add_argument(
        "--update", action="store_true", help="rewrite each case's expected output with the actual"
    )
    p.set_defaults(run="rules:test")


def _completion(sub: a.Sub) -> None:
    p = sub.add_parser(
        "completion",
        help='a shell completion script: eval "$(dkreason completion bash)" in ~/.bashrc',
    )
    p.add_argument("shell", choices=("bash", "zsh"))
    p.set_defaults(run="completion:completion")
