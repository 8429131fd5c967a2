"""`dkreason`: a thin CLI over KnowledgeManager.  Every DkError is one line on stderr, exit 2.

Heavy imports (rdflib, pyDatalog, lark) happen inside the commands so `--help` starts fast.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:
    from .manager import KnowledgeManager
    from .model import StreamRequest


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, like every other input error
        self.exit(2, f"{self.prog}: error: {message}\n")


def main(argv: Sequence[str] | None = None) -> int:
    parser = _build()
    args = parser.parse_args(argv)
    from .errors import DkError

    try:
        code: int = args.run(args)
        return code
    except DkError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def _build() -> _Parser:
    parser = _Parser(prog="dkreason", description=__doc__.split("\n")[0] if __doc__ else None)
    sub = parser.add_subparsers(required=True, metavar="COMMAND", parser_class=_Parser)

    def config(p: argparse.ArgumentParser) -> None:
        p.add_argument("--config", required=True, type=Path, help="TOML config file")

    p = sub.add_parser("match", help="the topics each feature of a formula is read from")
    config(p)
    p.add_argument("--json", action="store_true", help="print the stream request as JSON")
    p.add_argument("formula")
    p.set_defaults(run=_match)

    p = sub.add_parser("progress", help="verdicts of formulas over a JSON-lines state file")
    p.add_argument("--states", required=True, type=Path,
                   help='JSON lines: {"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5}}')
    p.add_argument("--config", type=Path, help="TOML config: quantifiers range over its objects")
    p.add_argument("--json", action="store_true", help="one JSON line per formula")
    p.add_argument("formulas", nargs="+", metavar="FORMULA")
    p.set_defaults(run=_progress)

    p = sub.add_parser("explain", help="why each topic matched, or why one did not")
    config(p)
    p.add_argument("formula")
    p.add_argument("--feature", help='only this ground feature, e.g. "Altitude[uav2]"')
    p.add_argument("--topic", help="only this topic; explains why it was not chosen if not")
    p.add_argument("--format", choices=("text", "json", "dot"), default="text")
    p.set_defaults(run=_explain)

    p = sub.add_parser("specs", help="list, show, add or remove topic specifications")
    specs = p.add_subparsers(required=True, metavar="ACTION", parser_class=_Parser)
    for action, helptext in (("list", "every topic specification"),
                             ("show", "one topic specification"),
                             ("add", "add an SSL_T topic specification (saved to the specs file)"),
                             ("remove", "remove a topic specification (saved to the specs file)")):
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
    request = _km(args).check_formula(args.formula)
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
    from .progress import Progressor
    from .progress.states import read_states

    progressor = Progressor.with_knowledge(_km(args)) if args.config else Progressor()
    for formula in args.formulas:
        progressor.add(formula)
    verdicts = []

    def emit(batch: list[Any]) -> None:
        for v in batch:
            verdicts.append(v)
            if args.json:
                print(json.dumps(v.to_json(), ensure_ascii=False, default=str), flush=True)
            else:
                value = {True: "true", False: "FALSE", None: "unknown"}[v.verdict]
                when = "at end" if v.at_end else "at"
                print(f"{when} {v.time}: {value}  {v.formula}" +
                      (f"\n    {v.witness}" if v.witness else ""), flush=True)

    for time, values in read_states(args.states):
        emit(progressor.step(time, values))
    emit(progressor.finish())
    return exit_status([v.verdict for v in verdicts])


def exit_status(verdicts: list[bool | None]) -> int:
    """0: every formula held; 1: one was violated; 3: none violated, one left unknown."""
    if False in verdicts:
        return 1
    return 0 if all(verdicts) else 3


def render_text(request: StreamRequest) -> str:
    """Thesis listings 6.2–6.4 and 6.8–6.10, plus where remote topics come from."""
    lines = []
    for f in request.features:
        lines += [f"Feature: {f.feature.key}", "Topics to merge:" if f.topics
                  else "Topics to merge: none"]
        for t in f.topics:
            ids = "".join(f"Id: {k} = {v}, " for k, v in t.filter)
            where = "" if t.platform == request.local else \
                f" (platform {t.platform}, as {t.as_feature}[{', '.join(t.as_args)}])"
            lines.append(f"  Topic: {t.topic}{where}, Message type: {t.msgtype}, {ids}"
                         f"Field: {t.field}")
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
