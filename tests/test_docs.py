"""The documentation: the site builds with `mkdocs build --strict` (no broken link, page or
API reference), and the README stays a short front page that names every command."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dkreason.cli.parser import build

REPO = Path(__file__).resolve().parents[1]


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    pytest.importorskip("mkdocs")
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "-d", str(tmp_path)],
        cwd=REPO,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    reference = (tmp_path / "reference" / "index.html").read_text(encoding="utf-8")
    assert "KnowledgeManager" in reference and "from_config" in reference


def test_the_readme_is_short_and_its_table_names_every_command() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 300
    sub = next(a for a in build(None)._actions if isinstance(a, argparse._SubParsersAction))
    commands = set(sub.choices)
    table = set(re.findall(r"^\| `dkreason (\w+)", readme, re.M))
    assert commands <= table
    for page in re.findall(r"\]\((docs/[\w-]+\.md)", readme):
        assert (REPO / page).is_file(), page
