"""The rule author's commands: rules check, query, test — each one façade call, rendered."""

from __future__ import annotations

import argparse
import json

from ..errors import DkError
from ..manager import KnowledgeManager
from . import render


def check(args: argparse.Namespace) -> int:
    if args.replace and args.config is not None:
        raise DkError("--replace is for rule files without --config (a config says replace_rules)")
    found = KnowledgeManager.check_rules(args.files, args.config, args.replace)
    for d in found:
        print(f"{d.severity}: {d}")
    errors = sum(d.severity == "error" for d in found)
    print(
        f"{errors} error{'s' * (errors != 1)}, {len(found) - errors} warning"
        f"{'s' * (len(found) - errors != 1)}"
    )
    return 2 if errors else 0


def query(args: argparse.Namespace) -> int:
    if args.relations == (args.question is not None):
        raise DkError("give a query, or --relations")
    km = KnowledgeManager.from_config(args.config)
    render.warnings(km.rule_warnings)
    if args.relations:
        found = km.relations()
        if args.json:
            print(
                json.dumps(
                    [
                        {
                            "relation": r.relation.name,
                            "columns": list(r.relation.columns),
                            "kind": r.relation.kind or "derived",
                            "rows": r.rows,
                            "note": r.note,
                        }
                        for r in found
                    ],
                    ensure_ascii=False,
                    indent=2,
                )
            )
        else:
            print(render.relations(found))
        return 0
    answer = km.query(args.question)
    if args.json:
        print(json.dumps(answer.to_json(), ensure_ascii=False, indent=2))
    else:
        print(render.answer(answer))
    return 0


def test(args: argparse.Namespace) -> int:
    from ..golden import run

    outcomes = run(args.folder, update=args.update)
    for o in outcomes:
        print(f"{'ok' if o.passed else 'updated' if o.updated else 'FAIL':<8}{o.name}")
        if not o.passed and not o.updated:
            print(o.diff, end="" if o.diff.endswith("\n") else "\n")
    failed = sum(not o.passed and not o.updated for o in outcomes)
    updated = sum(o.updated for o in outcomes)
    print(
        f"{len(outcomes) - failed - updated} passed, {failed} failed"
        + (f", {updated} updated" if updated else "")
    )
    return 1 if failed else 0
