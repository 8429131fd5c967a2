"""`specs add/remove` edit the file through its parsed model: no layout, line end, concurrent
editor or kill loses a topic; the file keeps its mode and symlinks."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.errors import DkError
from dkreason.parse.sslt import format_xml, parse_text, parse_xml, read_specs

REPO = Path(__file__).resolve().parents[1]
SSLT = (REPO / "specs" / "platform1.sslt").read_text()
NEW = "topic topic10:UavMsg contains Altitude(uav2) = msg.alt for uav2 = msg.id"


def platform(tmp_path: Path, specs: str | bytes, name: str = "specs.sslt") -> Path:
    """A one-platform config over the bundled platform 1 ontology and the given specs."""
    shutil.copy(REPO / "ontologies" / "platform1.owl", tmp_path / "p1.owl")
    data = specs.encode() if isinstance(specs, str) else specs
    (tmp_path / name).write_bytes(data)
    (tmp_path / name).chmod(0o644)
    config = tmp_path / "config.toml"
    config.write_text(
        f'local = "platform1"\n[platforms.platform1]\nontology = "p1.owl"\nspecs = "{name}"\n'
    )
    return config


def names(path: Path) -> list[str]:
    return [s.name for s in read_specs(path).specs]


def original() -> list[str]:
    return [s.name for s in parse_text(SSLT).specs]


def xml_text() -> str:
    return format_xml(parse_text(SSLT).specs)


def test_xml_on_one_line_keeps_every_other_topic(tmp_path: Path) -> None:
    config = platform(tmp_path, xml_text().replace("\n", ""), "specs.xml")
    km = KnowledgeManager.from_config(config)
    km.remove_topic("topic5")
    assert names(tmp_path / "specs.xml") == [n for n in original() if n != "topic5"]
    km.add_topic(NEW)
    assert names(tmp_path / "specs.xml") == [n for n in original() if n != "topic5"] + ["topic10"]


def test_xml_closing_tags_on_one_line_do_not_nest_the_new_topic(tmp_path: Path) -> None:
    text = xml_text().replace("</Topic>\n</Topic_specs>", "</Topic></Topic_specs>")
    config = platform(tmp_path, text, "specs.xml")
    KnowledgeManager.from_config(config).add_topic(NEW)
    spec = parse_xml((tmp_path / "specs.xml").read_bytes())
    assert [s.name for s in spec.specs] == [*original(), "topic10"]
    assert spec.specs[-2] == parse_text(SSLT).specs[-1]  # topic9 unchanged


def test_empty_xml_root_is_opened_for_a_new_topic(tmp_path: Path) -> None:
    config = platform(tmp_path, '<?xml version="1.0"?>\n<Topic_specs/>\n', "specs.xml")
    KnowledgeManager.from_config(config).add_topic(NEW)
    assert names(tmp_path / "specs.xml") == ["topic10"]


def test_two_sslt_topics_on_one_line(tmp_path: Path) -> None:
    lines = SSLT.splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith("topic topic3:"))
    lines[i : i + 2] = [lines[i] + "  " + lines[i + 1]]
    config = platform(tmp_path, "\n".join(lines) + "\n")
    KnowledgeManager.from_config(config).remove_topic("topic3")
    assert names(tmp_path / "specs.sslt") == [n for n in original() if n != "topic3"]


@pytest.mark.parametrize("odd", ["\x0c", "\r", "\x85", "\x1e", "\u2028"])
def test_unusual_line_breaks_in_a_comment(tmp_path: Path, odd: str) -> None:
    config = platform(tmp_path, f"# a comment{odd}with an odd break\n" + SSLT)
    KnowledgeManager.from_config(config).remove_topic("topic5")
    assert names(tmp_path / "specs.sslt") == [n for n in original() if n != "topic5"]


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_line_ends_are_kept(tmp_path: Path, newline: str) -> None:
    config = platform(tmp_path, SSLT.replace("\n", newline))
    km = KnowledgeManager.from_config(config)
    km.remove_topic("topic4")
    km.add_topic(NEW)
    data = (tmp_path / "specs.sslt").read_bytes().decode()
    assert data.count(newline) == len(original()) and "\n" not in data.replace(newline, "")
    assert names(tmp_path / "specs.sslt") == [n for n in original() if n != "topic4"] + ["topic10"]


def test_mode_symlink_and_temporaries(tmp_path: Path) -> None:
    config = platform(tmp_path, SSLT, "real.sslt")
    (tmp_path / "real.sslt").chmod(0o640)
    (tmp_path / "specs.sslt").symlink_to("real.sslt")
    config.write_text(config.read_text().replace("real.sslt", "specs.sslt"))
    (tmp_path / ".real.sslt.abc123.tmp").write_text("left by a killed editor")
    KnowledgeManager.from_config(config).add_topic(NEW)
    assert (tmp_path / "specs.sslt").is_symlink()
    assert names(tmp_path / "real.sslt")[-1] == "topic10"
    assert (tmp_path / "real.sslt").stat().st_mode & 0o777 == 0o640
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*.tmp"))


def test_removing_a_missing_topic_is_one_line_exit_2(tmp_path: Path) -> None:
    config = platform(tmp_path, SSLT)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dkreason.cli",
            "specs",
            "remove",
            "--config",
            str(config),
            "topic99",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "topic99" in done.stderr
    assert (tmp_path / "specs.sslt").read_text() == SSLT


@pytest.mark.parametrize("action", ["add", "remove"])
def test_a_full_disk_is_one_line_and_the_file_stays_intact(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], action: str
) -> None:
    from dkreason.cli import main

    config = platform(tmp_path, SSLT)

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    argument = NEW if action == "add" else "topic4"
    assert main(["specs", action, "--config", str(config), argument]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "specs.sslt" in err and "No space left" in err, err
    assert (tmp_path / "specs.sslt").read_text() == SSLT
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_topic_added_behind_our_back_is_refused_not_duplicated(tmp_path: Path) -> None:
    config = platform(tmp_path, SSLT)
    km = KnowledgeManager.from_config(config)
    with (tmp_path / "specs.sslt").open("a") as out:
        out.write(NEW + "\n")
    with pytest.raises(DkError, match="topic10 is already specified"):
        km.add_topic(NEW)
    assert names(tmp_path / "specs.sslt") == [*original(), "topic10"]
    assert "topic10" not in km.list_topics()


def test_fifty_concurrent_editors(tmp_path: Path) -> None:
    """25 adds and 25 removes at once: every add present, every remove applied, mode kept."""
    extra = "\n".join(
        f"topic old{i}:UavMsg contains Altitude(uav1) = msg.alt{i} for uav1 = msg.id"
        for i in range(25)
    )
    config = platform(tmp_path, SSLT + extra + "\n")
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    argv = [sys.executable, "-m", "dkreason.cli", "specs"]
    procs = [
        subprocess.Popen(
            [
                *argv,
                "add",
                "--config",
                str(config),
                f"topic new{i}:UavMsg contains Altitude(uav2) = msg.alt for uav2 = msg.id",
            ],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        for i in range(25)
    ]
    procs += [
        subprocess.Popen(
            [*argv, "remove", "--config", str(config), f"old{i}"],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        for i in range(25)
    ]
    errors = [p.communicate(timeout=600)[1] for p in procs]
    assert [p.returncode for p in procs] == [0] * 50, errors
    assert sorted(names(tmp_path / "specs.sslt")) == sorted(
        [*original(), *(f"new{i}" for i in range(25))]
    )
    assert (tmp_path / "specs.sslt").stat().st_mode & 0o777 == 0o644
