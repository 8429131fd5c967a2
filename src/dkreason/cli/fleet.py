"""The fleet commands: `batch` (many runs into the results database) and `results` (what the
database holds: a summary, rows, Parquet, or what changed between two batches)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from ..manager import KnowledgeManager
from ..results import Results, Row
from ..stream.units import since
from . import render
from .options import formulas, policy


def batch(args: argparse.Namespace) -> int:
    km = KnowledgeManager.from_config(args.config)
    texts = formulas(args)
    with _progress(not args.json) as (on_start, on_run):

        def each(rows: list[Row]) -> None:
            if args.json:
                for row in rows:
                    print(json.dumps(row.to_json(), ensure_ascii=False), flush=True)
            on_run(rows)

        done = km.batch(
            args.sources,
            texts,
            policy(args),
            remap=args.remap,
            clock=args.clock,
            msg=args.msg,
            typestore=args.typestore,
            jobs=args.jobs,
            scheduler=args.scheduler,
            db=args.db,
            resume=args.resume,
            timeout=args.timeout,
            on_start=on_start,
            on_run=each,
        )
    with Results(args.db) as results:
        if not args.json:
            _summary(results, done.batch_id, None)
        failed = args.fail_on_constraint and bool(results.violations(done.batch_id))
    return 1 if failed else done.status


def results(args: argparse.Namespace) -> int:
    with Results(args.db) as db:
        if args.diff:
            changes = db.diff(*args.diff)
            for c in changes:
                if args.json:
                    print(json.dumps(c.to_json(), ensure_ascii=False))
                else:
                    print(f"{c.run}: {c.formula}: {c.before or '-'} -> {c.after or '-'}")
            if not args.json:
                print(f"{len(changes)} verdict(s) changed from {args.diff[0]} to {args.diff[1]}")
            return 0
        batch_id = db.batch(args.batch)
        if args.parquet is not None:
            db.to_parquet(batch_id, args.parquet)
            print(f"batch {batch_id} written to {args.parquet}")
        elif args.json:
            for row in db.rows(batch_id, args.formula, args.verdict):
                print(json.dumps(row.to_json(), ensure_ascii=False))
        else:
            _summary(db, batch_id, args.formula, args.verdict)
    return 0


def _summary(db: Results, batch_id: str, formula: str | None, verdict: str | None = None) -> None:
    """Per formula the verdicts' counts, then the violated runs with when and why."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console(width=120)
    table = Table(title=f"dkreason batch {batch_id}", title_justify="left")
    for column in ("formula", "held", "violated", "undecided", "error"):
        table.add_column(column)
    for text, c in db.counts(batch_id).items():
        if formula is None or text == formula:
            table.add_row(
                escape(text), *(str(c[v]) for v in ("held", "violated", "undecided", "error"))
            )
    console.print(table)
    console.print(render.constraint_counts(db.violations(batch_id)))
    shown = db.rows(batch_id, formula, verdict or "violated")
    for row in shown:
        when = "" if row.t is None else f" at {since(row.t)}"
        console.print(
            f"{render.shout(False) if row.verdict == 'violated' else row.verdict}{when}: "
            f"{escape(row.run)}: {escape(row.formula)}"
            + (f"\n    {escape(row.witness)}" if row.witness else "")
            + (f"\n    error: {escape(row.error)}" if row.error else "")
        )


@contextmanager
def _progress(
    enabled: bool,
) -> Iterator[tuple[Callable[[str, str | None, int, int], None], Callable[[list[Row]], None]]]:
    """A progress bar on stderr (runs done of all, failures, messages/s); the batch id and the
    dashboard's address are said when the batch starts."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    bar = Progress(
        TextColumn("runs"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[failed]} failed, {task.fields[rate]} messages/s"),
        TimeRemainingColumn(),
        transient=True,
        disable=not (enabled and sys.stderr.isatty()),
    )
    task = bar.add_task("runs", total=None, failed=0, rate=0)
    seen = {"messages": 0.0, "failed": 0, "since": time.monotonic()}

    def on_start(batch_id: str, dashboard: str | None, todo: int, skipped: int) -> None:
        print(
            f"batch {batch_id}: {todo} run(s) to monitor"
            + (f", {skipped} done before" if skipped else "")
            + (f"; dashboard {dashboard}" if dashboard else ""),
            file=sys.stderr,
            flush=True,
        )
        seen["since"] = time.monotonic()
        bar.update(task, total=todo)

    def on_run(rows: list[Row]) -> None:
        if rows:
            seen["messages"] += rows[0].messages
            seen["failed"] += any(r.error for r in rows)
        rate = int(seen["messages"] / max(time.monotonic() - seen["since"], 1e-9))
        bar.update(task, advance=1, failed=int(seen["failed"]), rate=rate)

    with bar:
        yield on_start, on_run
