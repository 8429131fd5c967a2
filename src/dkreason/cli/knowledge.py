"""The knowledge commands: match, explain, specs, sort, init — each one façade call, rendered."""

from __future__ import annotations

import argparse
import json
import sys
import time

from ..manager import KnowledgeManager
from . import render


def match(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    km = KnowledgeManager.from_config(args.config)
    loaded = time.perf_counter()
    render.warnings(km.rule_warnings)
    request = km.check_formula(args.formula, max_delay=args.max_delay, best_source=args.best_source)
    if args.stats:
        print(
            f"stats: load {(loaded - start) * 1e3:.1f} ms, match "
            f"{(time.perf_counter() - loaded) * 1e3:.1f} ms",
            file=sys.stderr,
        )
        for name, (kind, rows) in sorted(km.stored().items()):
            print(f"stats: {kind:<5} {name:<20} {rows:>9}", file=sys.stderr)
    if args.json:
        print(json.dumps(request.to_json(), ensure_ascii=False))
    else:
        print(render.request(request))
    return 0


def explain(args: argparse.Namespace) -> int:
    from .. import explain as why

    km = KnowledgeManager.from_config(args.config)
    render.warnings(km.rule_warnings)
    result = km.explain(
        args.formula,
        args.feature,
        args.topic,
        max_delay=args.max_delay,
        best_source=args.best_source,
    )
    print(why.render(result, args.format, proof=args.proof, depth=args.depth))
    return 0


def specs(args: argparse.Namespace) -> int:
    from ..parse.sslt import format_spec, format_xml_topic

    km = KnowledgeManager.from_config(args.config)
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


def sort(args: argparse.Namespace) -> int:
    for name in KnowledgeManager.from_config(args.config).list_sort(args.sort, args.platform):
        print(name)
    return 0


def init(args: argparse.Namespace) -> int:
    made = KnowledgeManager.init(
        args.source,
        args.folder,
        robot=args.robot,
        topics=args.topics,
        msg=args.msg,
        typestore=args.typestore,
    )
    print(f"wrote {made.config}, {made.ontology}, {made.specs}")
    named = [f"{f.name}[{made.robot}]" for f in made.features]
    width = max(map(len, named))
    for name, f in zip(named, made.features, strict=True):
        print(f"  {name:<{width}}  {f.kind:<6}  {f.topic} {f.field}")
    first = made.features[0]
    test = {"number": " > 0", "bool": "", "string": ' != ""'}[first.kind]
    sources = " ".join(f"--source {s}" for s in args.source)
    print(f"next: dkreason monitor --config {made.config} {sources} 'always ({named[0]}{test})'")
    return 0
