"""Loading at fleet scale: parsed knowledge comes from the cache while its files are unchanged
(and never once one changed), and what the knowledge base stores grows with specs + objects,
never with their product."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.chapter7.workload import Workload, nine, write
from dkreason import KnowledgeManager, cache
from dkreason.kb import KnowledgeBase

from .conftest import REPO


@pytest.fixture
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("DKREASON_CACHE", str(folder))
    return folder


def _entries(folder: Path) -> set[str]:
    return {p.name for p in folder.glob("platform-*")}


def test_a_second_load_reads_the_cache_and_a_changed_file_is_parsed_again(
        tmp_path: Path, private_cache: Path) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    first = KnowledgeManager.from_config(config).list_topics()
    (entry,) = _entries(private_cache)
    KnowledgeManager.from_config(config)
    assert _entries(private_cache) == {entry}  # read, not written again

    specs = tmp_path / "w" / "ch7.sslt"
    specs.write_text(specs.read_text() + "topic late:M contains X(b1) = msg.v for b1 = msg.id\n")
    again = KnowledgeManager.from_config(config).list_topics()
    assert again == [*first, "late"]
    assert len(_entries(private_cache)) == 2

    ontology = tmp_path / "w" / "ch7.owl"  # a sort renamed: the specs naming it now fail
    ontology.write_text(ontology.read_text().replace('#b1"', '#b1x"'))
    with pytest.raises(Exception, match="b1"):
        KnowledgeManager.from_config(config)
    assert len(_entries(private_cache)) == 2  # a failed parse stores nothing


def test_a_damaged_entry_is_parsed_again(tmp_path: Path, private_cache: Path) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    topics = KnowledgeManager.from_config(config).list_topics()
    (entry,) = private_cache.glob("platform-*")
    entry.write_bytes(entry.read_bytes()[:100])
    assert KnowledgeManager.from_config(config).list_topics() == topics


def test_caching_can_be_turned_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DKREASON_CACHE", "off")
    assert cache.folder() is None
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    assert KnowledgeManager.from_config(config).list_topics()


def test_an_unwritable_cache_costs_only_the_parse(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("DKREASON_CACHE", str(blocker / "cache"))  # under a regular file
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    assert KnowledgeManager.from_config(config).list_topics()


def _stored(config: Path) -> dict[str, int]:
    """Rows per stored relation, as `dkreason match --stats` prints them."""
    done = subprocess.run([sys.executable, "-m", "dkreason.cli", "match", "--stats", "--config",
                           str(config), "X[b1]"], capture_output=True, text=True, check=True,
                          env=os.environ | {"PYTHONPATH": str(REPO / "src")})
    rows = {}
    for line in done.stderr.splitlines():
        words = line.split()
        if words[:2] in (["stats:", "view"], ["stats:", "input"]):
            rows[words[2]] = int(words[3])
    return rows


def test_stored_relations_grow_with_specs_plus_objects_not_their_product(
        tmp_path: Path) -> None:
    """Ten times the sorts, objects and specs (most specs over sorts): every relation holds
    at most ten times the rows, times 1.5 for the closures (a sort's ancestors, an object's
    sorts: the random hierarchy grows deeper, logarithmically), plus slack for the fixed part.
    The materialized sort × instance view this replaced held a hundred times the rows."""
    def workload(scale: int) -> Workload:
        return Workload(20 * scale, 30 * scale, 10 * scale, 30 * scale, 5 * scale, nine(),
                        sort_share=0.8)

    small = _stored(write(workload(1), tmp_path / "small"))
    large = _stored(write(workload(10), tmp_path / "large"))
    assert large.keys() == small.keys() and "sort_arg_at" in large and "member" in large
    for name, rows in large.items():
        assert rows <= 15 * small[name] + 50, (name, small[name], rows)


def test_what_the_cli_loads_is_what_the_api_loads(tmp_path: Path) -> None:
    config = write(Workload(30, 5, 5, 10, 5, nine(), sort_share=0.8), tmp_path / "w")
    stored = _stored(config)
    kb = KnowledgeBase.from_config(config)
    assert {n: r for n, (_, r) in kb.engine.sizes().items()} == stored
