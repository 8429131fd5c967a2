"""Rule files as read from disk: their text, and the facts of the tables they name
(`.input`), each fact with the file:line it comes from."""

from __future__ import annotations

import csv
import re
from dataclasses import replace
from pathlib import Path

from ..errors import DkError, RuleError, Span
from ..inputs.files import read_text
from .syntax import Fact, RuleFile, Table, Value, parse_rules

_INTEGER = re.compile(r"-?(0|[1-9][0-9]{0,17})")


def read_rule_file(path: Path, shown: str, shipped: bool = False) -> RuleFile:
    """A rule file, its tables' facts among its own (`shown`: its name in messages)."""
    rules = parse_rules(read_text(path), shown, path.parent, shipped)
    if not rules.tables:
        return rules
    return replace(rules, facts=rules.facts + tuple(f for t in rules.tables for f in read_table(t)))


def read_table(table: Table) -> list[Fact]:
    """A `.input` table's rows as facts: CSV, or TSV as Soufflé writes it (no quoting); a
    whole number is a number, any other cell a string, as a rule would quote it."""
    try:
        text = read_text(table.path)
    except DkError as exc:  # missing, unreadable, too large: said where the table is named
        raise RuleError(f".input {table.relation}: {exc}", table.span) from None
    reader = csv.reader(
        text.splitlines(),
        delimiter=table.delimiter,
        quoting=csv.QUOTE_MINIMAL if table.delimiter == "," else csv.QUOTE_NONE,
    )
    facts = []
    try:
        for n, cells in enumerate(reader, 1):
            if (table.headers and n == 1) or not cells:
                continue
            row: tuple[Value, ...] = tuple(int(c) if _INTEGER.fullmatch(c) else c for c in cells)
            facts.append(Fact(table.relation, row, Span(table.file, n)))
    except csv.Error as exc:
        raise RuleError(f"not a table row: {exc}", Span(table.file, reader.line_num)) from None
    return facts
