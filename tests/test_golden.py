"""`dkreason test DIR`: golden files, pretty JSON with relative paths; a difference is exit 1
with a unified diff, `--update` rewrites them.  The project's own policy tests are such files
(tests/golden)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dkreason.cli import main

from .conftest import REPO

GOLDEN = REPO / "tests" / "golden"


def test_the_projects_golden_files_hold(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["test", str(GOLDEN)])
    out = capsys.readouterr().out.splitlines()
    cases = sorted(p.name for p in GOLDEN.glob("*.json"))
    assert code == 0, "\n".join(out)
    assert out == [f"ok      {name}" for name in cases] + [f"{len(cases)} passed, 0 failed"]


def copy(tmp_path: Path) -> Path:
    """The golden folder and the data its configs name, at the same relative place."""
    shutil.copytree(REPO / "tests" / "data", tmp_path / "data")
    shutil.copytree(GOLDEN, tmp_path / "golden")
    return tmp_path / "golden"


def test_a_difference_is_a_unified_diff_and_exit_1_until_updated(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    folder = copy(tmp_path)
    case = folder / "single-speed.json"
    data = json.loads(case.read_text(encoding="utf-8"))
    data["expect"]["features"][0]["topics"][0]["field"] = "msg.speed"
    case.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")

    assert main(["test", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "FAIL    single-speed.json\n" in out
    assert "--- single-speed.json (expected)\n+++ single-speed.json (actual)\n" in out
    assert '-          "field": "msg.speed",\n+          "field": "msg.spd",\n' in out
    assert out.splitlines()[-1] == f"{len(list(folder.glob('*.json'))) - 1} passed, 1 failed"

    assert main(["test", "--update", str(folder)]) == 0
    assert "updated single-speed.json" in capsys.readouterr().out
    assert (
        json.loads(case.read_text(encoding="utf-8"))["expect"]["features"][0]["topics"][0]["field"]
        == "msg.spd"
    )
    assert main(["test", str(folder)]) == 0
    assert not list(folder.glob(".*"))  # nothing left beside the golden files


def test_paths_are_relative_to_the_case_wherever_it_runs(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """The golden files name ../data/thesis/specs/platform1.sslt, not the machine's path."""
    folder = copy(tmp_path)
    assert main(["test", str(folder)]) == 0
    explained = json.loads((folder / "explain-strict.json").read_text(encoding="utf-8"))
    text = json.dumps(explained)
    assert "../data/strict.dl:9" in text and str(tmp_path) not in text


def test_a_file_that_is_no_test_case_is_one_error_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    (tmp_path / "x.json").write_text('{"config": "c.toml"}')
    assert main(["test", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"error: {tmp_path / 'x.json'}: a test case is a JSON object with a config and one of "
        "match, explain, query\n"
    )
