"""A policy's rule files read as one program: each named as messages show it, its constants
resolved, and checked as a whole."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ..parse.config import SCHEMA, SHIPPED_RULES, shipped_policy
from .check import Diagnostic, Known, check
from .resolve import Names, resolve
from .syntax import RuleFile
from .tables import read_rule_file


def shown(path: Path, base: Path | None) -> str:
    """A rule file as messages and explanations name it, the same wherever dkreason is
    installed or run: one of dkreason's own as rules/NAME.dl, another relative to `base` (the
    config's folder), else to the current folder when it lies below it."""
    if path.resolve().is_relative_to(SHIPPED_RULES.resolve()):
        return "rules/" + path.resolve().relative_to(SHIPPED_RULES.resolve()).as_posix()
    if base is not None:
        return os.path.relpath(path, base)
    relative = os.path.relpath(path)
    return relative if not relative.startswith("..") else str(path)


def read_policy(
    paths: Sequence[Path], names: Names | None = None, base: Path | None = None
) -> list[RuleFile]:
    """The schema, then each rule file, read (a file's tables too), with their constants
    resolved by `names` (none: kept as written)."""
    files = []
    for path in (SCHEMA, *paths):
        own = path.resolve().is_relative_to(SHIPPED_RULES.resolve())
        read = read_rule_file(path, shown(path, base), own)
        files.append(resolve(read, names) if names is not None else read)
    return files


def check_files(
    paths: Sequence[Path], replace: bool = False, known: Known | None = None
) -> list[Diagnostic]:
    """Every error and warning of these rule files as a policy: added to the shipped one, or
    (`replace`) the whole policy.  A file that cannot be read raises its one error."""
    policy = [*(() if replace else shipped_policy()), *paths]
    return check(read_policy(list(dict.fromkeys(policy))), known)
