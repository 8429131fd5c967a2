"""The TOML config: which platform is local, each platform's files, mappings, extra rules.

    local = "platform1"
    rules = ["rules/extensions/subsumption.dl"]    # optional extension rule files
    [platforms.platform1]
    ontology = "ontologies/platform1.owl"
    specs = "specs/platform1.sslt"                  # .sslt or .xml; optional
    [platforms.platform2]                           # no files: fetched from the platform's
                                                    # node (`dkreason monitor --live`)
    [[mappings]]
    source = "platform1"
    target = "platform2"
    file = "mappings/platform1-platform2.cowl.xml"

Paths are relative to the config file (rule files may also be given relative to the
directory holding dkreason's own `rules/`).
"""

from __future__ import annotations

import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span
from .files import read_text

RULES_HOME = Path(__file__).resolve().parents[3]


@dataclass(frozen=True, slots=True)
class PlatformFiles:
    name: str
    ontology: Path | None  # None: the knowledge comes from the platform's live node
    specs: Path | None


@dataclass(frozen=True, slots=True)
class MappingFiles:
    source: str
    target: str
    file: Path


@dataclass(frozen=True, slots=True)
class Config:
    path: Path
    local: str
    platforms: tuple[PlatformFiles, ...]
    mappings: tuple[MappingFiles, ...]
    rules: tuple[Path, ...]


def read_config(path: Path) -> Config:
    file = str(path)
    try:
        data = tomllib.loads(read_text(path))
    except RecursionError:
        raise ParseError("TOML nested too deeply", Span(file)) from None
    except tomllib.TOMLDecodeError as exc:  # position only in the message before Python 3.14
        where = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
        line, col = (int(where.group(1)), int(where.group(2))) if where else (0, 0)
        message = str(exc).split(" (at ")[0]
        raise ParseError(f"TOML syntax error: {message}", Span(file, line, col)) from None
    base = path.parent

    def at(value: str) -> Path:  # normalised, so messages say ontologies/x.owl, not a/../x.owl
        return Path(os.path.normpath(base / value))

    def fail(message: str) -> DkError:
        return ParseError(message, Span(file))

    def text(table: dict[str, Any], key: str, where: str) -> str:
        value = table.get(key)
        if not isinstance(value, str) or not value:
            raise fail(f"{where}: {key!r} must be a non-empty string")
        if not value.isprintable():
            raise fail(f"{where}: {key!r} holds a control character ({value!r})")
        return value

    _only(data, {"local", "platforms", "mappings", "rules"}, "top level", fail)
    platforms_raw = data.get("platforms")
    if not isinstance(platforms_raw, dict) or not platforms_raw:
        raise fail("no [platforms.NAME] table")
    platforms = []
    for name, table in platforms_raw.items():
        if not isinstance(table, dict):
            raise fail(f"platforms.{name} must be a table")
        _only(table, {"ontology", "specs"}, f"[platforms.{name}]", fail)
        section = f"[platforms.{name}]"
        if "specs" in table and "ontology" not in table:
            raise fail(f"{section}: specs without an ontology")
        platforms.append(PlatformFiles(name, *(
            at(text(table, key, section)) if key in table else None
            for key in ("ontology", "specs"))))
    names = [p.name for p in platforms]
    local = data.get("local", names[0] if len(names) == 1 else None)
    if local not in names:
        raise fail(f"local = {local!r} names no platform (platforms: {', '.join(names)})"
                   if local is not None else "several platforms: say which one is local")
    mappings = []
    if not isinstance(data.get("mappings", []), list):
        raise fail("mappings must be an array of tables ([[mappings]])")
    for i, table in enumerate(data.get("mappings", []), 1):
        if not isinstance(table, dict):
            raise fail(f"mappings entry {i} must be a table")
        _only(table, {"source", "target", "file"}, f"[[mappings]] {i}", fail)
        src, tgt = text(table, "source", f"[[mappings]] {i}"), text(table, "target",
                                                                      f"[[mappings]] {i}")
        for side in (src, tgt):
            if side not in names:
                raise fail(f"[[mappings]] {i}: platform {side!r} is not configured")
        if src == tgt:
            raise fail(f"[[mappings]] {i}: source and target are both {src!r}")
        mappings.append(MappingFiles(src, tgt, at(text(table, "file", f"[[mappings]] {i}"))))
    rules = data.get("rules", [])
    if not isinstance(rules, list) or not all(isinstance(r, str) and r.isprintable()
                                              for r in rules):
        raise fail("rules must be a list of rule file paths")
    return Config(path, local, tuple(platforms), tuple(mappings),
                  tuple(_rule_path(base, r, fail) for r in rules))


def _only(table: dict[str, Any], allowed: set[str], where: str, fail: Any) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise fail(f"{where}: unknown key {unknown[0]!r} (expected one of "
                   f"{', '.join(sorted(allowed))})")


def _rule_path(base: Path, written: str, fail: Any) -> Path:
    for candidate in (base / written, RULES_HOME / written):
        if candidate.is_file():
            return candidate
    raise fail(f"rule file {written!r} not found (relative to {base} or {RULES_HOME})")
