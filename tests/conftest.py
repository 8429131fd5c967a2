"""Shared fixtures: the thesis scenarios (tests/data/thesis) and comparison helpers."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]


def pytest_configure(config: pytest.Config) -> None:
    """Parsed knowledge is cached in a folder of this session's (dkreason.cache), never in
    the user's own ~/.cache, and signed with a key of this session's, never the user's own
    (XDG_STATE_HOME); CLI subprocesses inherit both."""
    os.environ["DKREASON_CACHE"] = tempfile.mkdtemp(prefix="dkreason-cache-")
    os.environ["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="dkreason-state-")


def pytest_unconfigure(config: pytest.Config) -> None:
    for name in ("DKREASON_CACHE", "XDG_STATE_HOME"):
        shutil.rmtree(os.environ.pop(name, ""), ignore_errors=True)


SCENARIOS = REPO / "tests" / "data" / "thesis"
"""The thesis' case studies, cleaned, with expected outputs (vendored from the project's
shared reference material: they are the golden test data)."""


def formulas() -> dict[str, str]:
    """formulas.txt: id → formula text."""
    out = {}
    for line in (SCENARIOS / "formulas.txt").read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            key, text = line.split(None, 1)
            out[key] = text.strip()
    return out


def entity_bomb(root: str) -> str:
    """A billion-laughs document: nine levels of ten-fold entity expansion."""
    levels = "".join(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10))
    return (
        f'<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY l0 "lol">{levels}]>\n<{root}>&l9;</{root}>\n'
    )


def topic_sets(request_json: dict[str, Any]) -> dict[tuple[str, tuple[str, ...]], set[Any]]:
    """Per (feature, args): the set of (platform, topic, msgtype, field, filter), as the
    scenario README says outputs are compared."""
    return {
        (f["feature"], tuple(f["args"])): {
            (
                t["platform"],
                t["topic"],
                t["msgtype"],
                t["field"],
                tuple(sorted(t["filter"].items())),
            )
            for t in f["topics"]
        }
        for f in request_json["features"]
    }


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    """A writable copy of the thesis scenario folder."""
    target = tmp_path / "thesis"
    shutil.copytree(SCENARIOS, target)
    for path in target.rglob("*"):
        path.chmod(0o755 if path.is_dir() else 0o644)
    return target


@pytest.fixture(scope="session")
def traffic(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The traffic example's recording (examples/traffic/simulate.py), made once."""
    import subprocess
    import sys

    target = tmp_path_factory.mktemp("traffic") / "recording"
    subprocess.run(
        [sys.executable, str(REPO / "examples" / "traffic" / "simulate.py"), str(target)],
        check=True,
        capture_output=True,
    )
    return target
