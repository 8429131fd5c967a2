"""The TOML config: which platform is local, each platform's files, mappings, extra rules.

    local = "platform1"
    rules = ["rules/extensions/subsumption.dl"]    # optional rule files, added to the shipped
    replace_rules = false                          # policy; true: they are the whole policy
    [imports]                                       # optional: owl:imports IRI → file, for
    "http://www.w3.org/ns/ssn/" = "ssn.ttl"         # imports no catalog-v001.xml resolves
    [platforms.platform1]
    ontology = "ontologies/platform1.owl"           # a file, or a list of files
    imports = "skip"                                # optional: an unresolved import is a
                                                    # warning, not an error
    reasoning = "owl-rl"                            # optional: OWL 2 RL memberships and
                                                    # sameAs become facts (default "none")
    adapters = ["properties", "sosa"]               # optional: features from properties
                                                    # (rules/adapters/NAME.dl, or a path to
                                                    # a rule file of one's own)
    specs = "specs/platform1.sslt"                  # .sslt or .xml; optional
    namespace = "/robot1"                           # optional: relative topic names resolve
                                                    # under it, as ROS resolves them
    [platforms.platform2]                           # no files: fetched from the platform's
                                                    # node (`dkreason monitor --live`)
    [[mappings]]
    source = "platform1"
    target = "platform2"
    file = "mappings/platform1-platform2.cowl.xml"

Paths are relative to the config file; a rule file named `rules/NAME.dl` that is not there is
one of dkreason's own (`rules/matching.dl`, `rules/extensions/subsumption.dl`), so a replacing
policy can keep some shipped files.  `Config.rules` is the whole policy, in load order; the
schema (`rules/schema.dl`: the relations Python asserts and asks) is always loaded first.
"""

from __future__ import annotations

import importlib.resources
import os
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span
from ..inputs.files import read_text

_NAMESPACE = re.compile(r"/|(/[A-Za-z_][A-Za-z0-9_]*)+/?")
SHIPPED_RULES = Path(str(importlib.resources.files("dkreason.rules")))
SCHEMA = SHIPPED_RULES / "schema.dl"
ADAPTERS = SHIPPED_RULES / "adapters"
ADAPTER_SCHEMA = ADAPTERS / "schema.dl"  # what Python and adapters share


def shipped_policy() -> tuple[Path, ...]:
    """The shipped matching policy: every rule file of `rules/` but the schema."""
    return tuple(sorted(p for p in SHIPPED_RULES.glob("*.dl") if p != SCHEMA))


@dataclass(frozen=True, slots=True)
class PlatformFiles:
    name: str
    ontology: tuple[Path, ...]  # empty: the knowledge comes from the platform's live node
    specs: Path | None
    namespace: str | None = None  # ROS namespace of the platform's relative topic names
    skip_imports: bool = False  # an owl:imports found nowhere is a warning, not an error
    reasoning: str = "none"  # "owl-rl": OWL 2 RL memberships and sameAs become facts
    # adapter rule files (rules/adapters/NAME.dl, or one's own), run over its triples
    adapters: tuple[Path, ...] = ()


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
    imports: dict[str, Path] = field(default_factory=dict)  # owl:imports IRI → file


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

    _only(
        data,
        {"local", "platforms", "mappings", "rules", "replace_rules", "imports"},
        "top level",
        fail,
    )
    imports_raw = data.get("imports", {})
    if not isinstance(imports_raw, dict):
        raise fail("[imports] must be a table of ontology IRI = file")
    imports = {iri: at(text(imports_raw, iri, "[imports]")) for iri in imports_raw}
    platforms_raw = data.get("platforms")
    if not isinstance(platforms_raw, dict) or not platforms_raw:
        raise fail("no [platforms.NAME] table")
    platforms = []
    for name, table in platforms_raw.items():
        if not isinstance(table, dict):
            raise fail(f"platforms.{name} must be a table")
        _only(
            table,
            {"ontology", "specs", "namespace", "imports", "reasoning", "adapters"},
            f"[platforms.{name}]",
            fail,
        )
        section = f"[platforms.{name}]"
        if "specs" in table and "ontology" not in table:
            raise fail(f"{section}: specs without an ontology")
        namespace = text(table, "namespace", section) if "namespace" in table else None
        if namespace is not None and not _NAMESPACE.fullmatch(namespace):
            raise fail(
                f"{section}: namespace {namespace!r} is not an absolute ROS namespace like /robot1"
            )
        written = table.get("ontology", [])
        listed = written if isinstance(written, list) and written else [written]
        ontology = (
            tuple(at(text({"ontology": x}, "ontology", section)) for x in listed)
            if "ontology" in table
            else ()
        )
        specs = at(text(table, "specs", section)) if "specs" in table else None
        skip = table.get("imports", "follow")
        if skip not in ("follow", "skip"):
            raise fail(f'{section}: imports must be "follow" or "skip", not {skip!r}')
        reasoning = table.get("reasoning", "none")
        if reasoning not in ("none", "owl-rl"):
            raise fail(f'{section}: reasoning must be "none" or "owl-rl", not {reasoning!r}')
        adapters = _adapters(base, table.get("adapters", []), section, fail)
        platforms.append(
            PlatformFiles(name, ontology, specs, namespace, skip == "skip", reasoning, adapters)
        )
    names = [p.name for p in platforms]
    local = data.get("local", names[0] if len(names) == 1 else None)
    if local not in names:
        raise fail(
            f"local = {local!r} names no platform (platforms: {', '.join(names)})"
            if local is not None
            else "several platforms: say which one is local"
        )
    mappings = []
    if not isinstance(data.get("mappings", []), list):
        raise fail("mappings must be an array of tables ([[mappings]])")
    for i, table in enumerate(data.get("mappings", []), 1):
        if not isinstance(table, dict):
            raise fail(f"mappings entry {i} must be a table")
        _only(table, {"source", "target", "file"}, f"[[mappings]] {i}", fail)
        src, tgt = (
            text(table, "source", f"[[mappings]] {i}"),
            text(table, "target", f"[[mappings]] {i}"),
        )
        for side in (src, tgt):
            if side not in names:
                raise fail(f"[[mappings]] {i}: platform {side!r} is not configured")
        if src == tgt:
            raise fail(f"[[mappings]] {i}: source and target are both {src!r}")
        mappings.append(MappingFiles(src, tgt, at(text(table, "file", f"[[mappings]] {i}"))))
    rules = data.get("rules", [])
    if not isinstance(rules, list) or not all(
        isinstance(r, str) and r.isprintable() for r in rules
    ):
        raise fail("rules must be a list of rule file paths")
    replace = data.get("replace_rules", False)
    if not isinstance(replace, bool):
        raise fail("replace_rules must be true or false")
    if replace and not rules:
        raise fail("replace_rules = true needs the rule files that replace the shipped policy")
    own = tuple(dict.fromkeys(_rule_path(base, r, fail) for r in rules))
    shipped = () if replace else shipped_policy()
    policy = (*shipped, *(p for p in own if p not in shipped))
    return Config(path, local, tuple(platforms), tuple(mappings), policy, imports)


def _only(table: dict[str, Any], allowed: set[str], where: str, fail: Any) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise fail(
            f"{where}: unknown key {unknown[0]!r} (expected one of {', '.join(sorted(allowed))})"
        )


def shipped_adapters() -> tuple[str, ...]:
    """The names of the shipped adapters (rules/adapters/NAME.dl)."""
    return tuple(sorted(p.stem for p in ADAPTERS.glob("*.dl") if p != ADAPTER_SCHEMA))


def _adapters(base: Path, written: Any, section: str, fail: Any) -> tuple[Path, ...]:
    if not isinstance(written, list) or not all(
        isinstance(a, str) and a and a.isprintable() for a in written
    ):
        raise fail(f"{section}: adapters must be a list of adapter names or rule file paths")
    try:
        return adapter_paths(written, base)
    except DkError as exc:
        raise fail(f"{section}: {exc}") from None


def adapter_paths(written: Sequence[str], base: Path) -> tuple[Path, ...]:
    """`adapters = [...]`: a shipped adapter by name, or a rule file of one's own by path
    (relative to `base`); anything else is one error naming it."""
    found = []
    for name in written:
        if name in shipped_adapters():
            found.append(ADAPTERS / f"{name}.dl")
        elif name.endswith(".dl") and (base / name).is_file():
            found.append(Path(os.path.normpath(base / name)))
        else:
            raise DkError(
                f"unknown adapter {name!r} (shipped: {', '.join(shipped_adapters())}; or the "
                f"path of a .dl rule file)"
            )
    return tuple(dict.fromkeys(found))


def _rule_path(base: Path, written: str, fail: Any) -> Path:
    if (base / written).is_file():
        return Path(os.path.normpath(base / written))
    shipped = written.removeprefix("rules/")
    if (
        shipped != written
        and (SHIPPED_RULES / shipped).is_file()
        and SHIPPED_RULES / shipped != SCHEMA
    ):
        return SHIPPED_RULES / shipped
    raise fail(
        f"rule file {written!r} not found (relative to {base}, or rules/NAME.dl for "
        f"one of dkreason's own)"
    )
