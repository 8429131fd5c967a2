"""`dkreason test DIR`: golden test cases, kept as Soufflé's suite keeps them, one JSON file
each (pretty, so a difference is a readable diff):

    {
      "config": "policy.toml",                       relative to the case file
      "match": "always (Altitude[uav2] > 10)",       or "explain" (with "feature", "topic",
                                                     "proof"), or "query"
      "expect": {...}                                the request, explanation, answer, or
    }                                                {"error": "…"}

Every case under DIR (`*.json`, recursively) is run against its config's knowledge base
(loaded once per config) and its output compared with `expect`; a case differs as a unified
diff, and `update` rewrites `expect` with what was found.  Paths in the output are relative to
the case's folder (rule files relative to their config, or rules/NAME.dl), so the files read
the same on every machine.
"""

from __future__ import annotations

import difflib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import DkError, Span, one_line
from .explain import to_json
from .inputs.files import json_value, read_text, write_atomic
from .manager import KnowledgeManager

_ACTIONS = ("match", "explain", "query")


@dataclass(frozen=True, slots=True)
class Outcome:
    """A case run: passed, or the unified diff of expected against actual (`updated`: the
    case file now expects the actual)."""

    name: str
    passed: bool
    diff: str = ""
    updated: bool = False


def run(folder: Path, update: bool = False) -> list[Outcome]:
    """Every case under `folder`, in name order."""
    if not folder.is_dir():
        raise DkError(f"{folder}: not a folder of test cases")
    loaded: dict[Path, KnowledgeManager | DkError] = {}
    return [
        _run(path, path.relative_to(folder).as_posix(), loaded, update)
        for path in sorted(folder.rglob("*.json"))
    ]


def _run(
    path: Path, name: str, loaded: dict[Path, KnowledgeManager | DkError], update: bool
) -> Outcome:
    case = json_value(read_text(path), Span(str(path)), exact=False)
    actions = [a for a in _ACTIONS if isinstance(case, dict) and a in case]
    if len(actions) != 1 or not isinstance(case.get("config"), str):
        raise DkError(
            f"{path}: a test case is a JSON object with a config and one of {', '.join(_ACTIONS)}"
        )
    found = relative(_actual(case, actions[0], path.parent / case["config"], loaded), path.parent)
    expected = _pretty(case.get("expect"))
    if _pretty(found) == expected:
        return Outcome(name, True)
    diff = "".join(
        difflib.unified_diff(
            expected.splitlines(keepends=True),
            _pretty(found).splitlines(keepends=True),
            f"{name} (expected)",
            f"{name} (actual)",
        )
    )
    if update:  # in one step, and no lock file left beside a golden file
        write_atomic(path, _pretty({**case, "expect": found}).encode())
    return Outcome(name, False, diff, update)


def _actual(
    case: dict[str, Any],
    action: str,
    config: Path,
    loaded: dict[Path, KnowledgeManager | DkError],
) -> Any:
    """What the case's command gives: a request, an explanation or an answer as JSON, or
    the one line of its error."""
    key = config.resolve()
    if key not in loaded:
        try:
            loaded[key] = KnowledgeManager.from_config(key)
        except DkError as exc:
            loaded[key] = exc
    try:
        km = loaded[key]
        if isinstance(km, DkError):
            raise km
        if action == "match":
            return km.check_formula(case["match"]).to_json()
        if action == "explain":
            found = km.explain(case["explain"], case.get("feature"), case.get("topic"))
            return to_json(found, proof=bool(case.get("proof", False)))
        return km.query(case["query"]).to_json()
    except DkError as exc:
        return {"error": one_line(str(exc))}


def relative(value: Any, folder: Path) -> Any:
    """`value` with every absolute path written relative to `folder` (`../` above it)."""
    if isinstance(value, dict):
        return {k: relative(v, folder) for k, v in value.items()}
    if isinstance(value, list):
        return [relative(v, folder) for v in value]
    if not isinstance(value, str) or "/" not in value:
        return value
    anchor = folder.resolve()
    for up, ancestor in enumerate([anchor, *anchor.parents][:-1]):
        value = value.replace(f"{ancestor}/", "../" * up)
    return value


def _pretty(value: Any) -> str:
    return json.dumps(value, ensure_ascii=False, indent=2) + "\n"
