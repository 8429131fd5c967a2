"""The installed package: a wheel holds every module, grammar and rule file, and runs from any
directory with no source tree beside it."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from .conftest import REPO

FORMULA = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The wheel built from a copy of the source (the tree stays clean), and a fresh venv it
    is installed into, non-editable.  Offline: the venv sees the test environment's
    dependencies through a path entry (not its .pth files, so not the editable dkreason)."""
    root = tmp_path_factory.mktemp("package")
    source = root / "source"
    for part in ("src", "rules"):
        shutil.copytree(
            REPO / part, source / part, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info")
        )
    for part in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / part, source / part)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--disable-pip-version-check",
            "-w",
            str(root / "dist"),
            str(source),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = (root / "dist").glob("dkreason-*.whl")
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, capture_output=True)
    (site,) = (venv / "lib").glob("python3*/site-packages")
    deps = [p for p in sys.path if p.endswith("site-packages")]
    (site / "test-dependencies.pth").write_text("\n".join(deps) + "\n")
    subprocess.run(
        [
            str(venv / "bin" / "python"),
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-index",
            "--disable-pip-version-check",
            str(wheel),
        ],
        check=True,
        capture_output=True,
    )
    return wheel, venv


def test_the_wheel_holds_every_module_grammar_and_rule_file(installed: tuple[Path, Path]) -> None:
    names = set(zipfile.ZipFile(installed[0]).namelist())
    src = REPO / "src"
    wanted = {
        p.relative_to(src).as_posix()
        for p in src.rglob("*")
        if p.suffix in (".py", ".lark") or p.name == "py.typed"
    }
    wanted |= {
        "dkreason/rules/" + p.relative_to(REPO / "rules").as_posix()
        for p in (REPO / "rules").rglob("*")
        if p.suffix in (".dl", ".py")
    }
    assert "dkreason/rules/schema.dl" in wanted and "dkreason/parse/mtl.lark" in wanted
    assert wanted - names == set()


def run_installed(venv: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    where = subprocess.run(
        [str(venv / "bin" / "python"), "-c", "import dkreason; print(dkreason.__file__)"],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert where.startswith(str(venv)), where  # the installed copy, not the source tree
    return subprocess.run(
        [str(venv / "bin" / "dkreason"), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_installed_package_matches_and_monitors_from_another_directory(
    installed: tuple[Path, Path], traffic: Path, tmp_path: Path
) -> None:
    venv = installed[1]
    config = str(REPO / "examples" / "federation.toml")
    matched = run_installed(venv, tmp_path, "match", "--config", config, FORMULA)
    assert matched.returncode == 0, matched.stderr
    assert "carstopic1 (platform platform2, as Speed[car12])" in matched.stdout
    monitored = run_installed(
        venv,
        tmp_path,
        "monitor",
        "--config",
        config,
        "--source",
        str(traffic),
        "--delay",
        "0.1",
        FORMULA,
    )
    assert monitored.returncode == 1, monitored.stderr  # car2's violation
    assert "300.02" in monitored.stdout


def test_production_code_never_imports_the_simulators() -> None:
    """dkreason.live.testing (ROS 2 robots replayed from a recording) is for tests, examples
    and benchmarks only."""
    import ast

    src = REPO / "src" / "dkreason"
    importers = []
    for path in src.rglob("*.py"):
        if path == src / "live" / "testing.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [f"{node.module}.{a.name}" for a in node.names]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if any("testing" in name.split(".") for name in names):
                importers.append(path.relative_to(src).as_posix())
    assert (src / "live" / "testing.py").is_file() and importers == []
