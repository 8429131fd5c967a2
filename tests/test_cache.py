"""Loading at fleet scale: parsed knowledge comes from the cache while its files are unchanged
(and never once one changed), and what the knowledge base stores grows with specs + objects,
never with their product."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason import KnowledgeManager, cache
from dkreason.datalog import Datalog
from dkreason.errors import SortError
from dkreason.kb import KnowledgeBase
from dkreason.workloads import Workload, nine, write

from .conftest import REPO


@pytest.fixture
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("DKREASON_CACHE", str(folder))
    return folder


def _entries(folder: Path) -> set[str]:
    return {p.name for p in folder.glob("platform-*")}


def test_a_second_load_reads_the_cache_and_a_changed_file_is_parsed_again(
    tmp_path: Path, private_cache: Path
) -> None:
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


def test_the_derived_views_come_from_the_cache_row_for_row(
    tmp_path: Path, private_cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The views and the spec checks are a function of the facts and the rules: a second load
    takes the rows the first one derived (and answers alike) without asking the engine."""
    config = write(Workload(30, 5, 5, 10, 5, nine(), sort_share=0.8), tmp_path / "w")
    formula = " and ".join(nine())
    first = KnowledgeManager.from_config(config)
    derived, answer = first.kb.engine.frozen(), first.check_formula(formula)

    def refuse(self: object) -> None:
        raise AssertionError("derived again")

    monkeypatch.setattr(Datalog, "materialize", refuse)
    again = KnowledgeManager.from_config(config)
    assert again.kb.engine.frozen() == derived
    assert again.check_formula(formula) == answer
    monkeypatch.undo()
    again.kb.remove_spec(again.kb.local, "rel0")  # a change re-derives what reads it, as before
    assert "topic_objects" in again.kb.rederived


def test_changed_specs_or_rules_derive_the_views_again(tmp_path: Path, private_cache: Path) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    KnowledgeManager.from_config(config)
    assert len(list(private_cache.glob("views-*"))) == 1
    specs = tmp_path / "w" / "ch7.sslt"
    specs.write_text(specs.read_text() + "topic late:M contains X(b1) = msg.v for b1 = msg.id\n")
    km = KnowledgeManager.from_config(config)
    assert "late" in {m.topic for m in km.check_formula("X[b1]").features[0].topics}
    assert len(list(private_cache.glob("views-*"))) == 2

    rules = tmp_path / "w" / "extra.dl"
    rules.write_text("# no rule, but another policy text\n")
    config.write_text(
        config.read_text().replace("local = ", 'rules = ["extra.dl"]\nlocal = ', 1)
        if "local = " in config.read_text()
        else 'rules = ["extra.dl"]\n' + config.read_text()
    )
    KnowledgeManager.from_config(config)
    assert len(list(private_cache.glob("views-*"))) == 3


def test_specs_that_fail_their_check_store_no_views(tmp_path: Path, private_cache: Path) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    specs = tmp_path / "w" / "ch7.sslt"
    specs.write_text(
        specs.read_text() + "topic bad:M contains X(Relation as a) = msg.v for some a = msg.id\n"
    )
    for _ in range(2):  # refused again: nothing was kept that would let it through
        with pytest.raises(SortError, match="Relation"):
            KnowledgeManager.from_config(config)
    assert not list(private_cache.glob("views-*"))


def test_a_views_entry_of_the_wrong_shape_is_derived_again(
    tmp_path: Path, private_cache: Path
) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    answer = KnowledgeManager.from_config(config).check_formula("X[b1]")
    (entry,) = private_cache.glob("views-*")
    with open(entry, "wb") as handle:  # unpickles, but is not what the rules derive
        pickle.dump({"member": [("p", "o")]}, handle)
    assert KnowledgeManager.from_config(config).check_formula("X[b1]") == answer


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


def test_an_unwritable_cache_costs_only_the_parse(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("DKREASON_CACHE", str(blocker / "cache"))  # under a regular file
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    assert KnowledgeManager.from_config(config).list_topics()


def _stored(config: Path) -> dict[str, int]:
    """Rows per stored relation, as `dkreason match --stats` prints them."""
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dkreason.cli",
            "match",
            "--stats",
            "--config",
            str(config),
            "X[b1]",
        ],
        capture_output=True,
        text=True,
        check=True,
        env=os.environ | {"PYTHONPATH": str(REPO / "src")},
    )
    rows = {}
    for line in done.stderr.splitlines():
        words = line.split()
        if words[:2] in (["stats:", "view"], ["stats:", "input"]):
            rows[words[2]] = int(words[3])
    return rows


def test_stored_relations_grow_with_specs_plus_objects_not_their_product(tmp_path: Path) -> None:
    """Ten times the sorts, objects and specs (most specs over sorts): every relation holds
    at most ten times the rows, times 1.5 for the closures (a sort's ancestors, an object's
    sorts: the random hierarchy grows deeper, logarithmically), plus slack for the fixed part.
    The materialized sort × instance view this replaced held a hundred times the rows."""

    def workload(scale: int) -> Workload:
        return Workload(
            20 * scale, 30 * scale, 10 * scale, 30 * scale, 5 * scale, nine(), sort_share=0.8
        )

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


def test_the_cache_stays_under_its_limit_dropping_what_was_used_longest_ago(
    tmp_path: Path, private_cache: Path
) -> None:
    entries: list[set[str]] = []  # each workload's own entries
    for n in (5, 6, 7):
        before = {p.name for p in private_cache.glob("*-*")}
        KnowledgeManager.from_config(write(Workload(30, 5, 5, 0, n, nine()), tmp_path / f"w{n}"))
        entries.append({p.name for p in private_cache.glob("*-*")} - before)
        for name in entries[-1]:  # made in this order, each workload a minute after the last
            os.utime(private_cache / name, (60.0 * n, 60.0 * n))
    KnowledgeManager.from_config(tmp_path / "w5" / "ch7.toml")  # the oldest, used again
    stranger = private_cache / "notes.txt"  # not named as an entry: never removed
    stranger.write_bytes(b"notes")
    os.utime(stranger, (1.0, 1.0))
    mine = [p for p in private_cache.iterdir() if p != stranger]
    size = sum(p.stat().st_size for p in mine)
    cache.prune(private_cache, limit=size * 2 // 3)
    left = {p.name for p in private_cache.iterdir()}
    assert entries[0] <= left  # used last
    assert not entries[1] & left  # used longest ago
    assert stranger.exists()
    assert sum((private_cache / n).stat().st_size for n in left - {stranger.name}) <= size * 2 // 3


def test_the_key_covers_the_whole_packages_code_with_no_list_to_forget(tmp_path: Path) -> None:
    from dkreason.cache import code_digest

    package = tmp_path / "pkg"
    (package / "parse").mkdir(parents=True)
    (package / "parse" / "owl.py").write_text("X = 1\n")
    (package / "parse" / "mtl.lark").write_text("start: 'a'\n")
    (package / "notes.txt").write_text("not code\n")
    seen = {code_digest(package)}
    (package / "notes.txt").write_text("still not code\n")
    assert code_digest(package) in seen
    (package / "parse" / "owl.py").rename(package / "owl.py")  # a module moved
    seen.add(code_digest(package))
    (package / "reason").mkdir()
    (package / "reason" / "entail.py").write_text("Y = 2\n")  # a module added
    seen.add(code_digest(package))
    (package / "parse" / "mtl.lark").write_text("start: 'b'\n")  # a grammar changed
    seen.add(code_digest(package))
    assert len(seen) == 4


# ---- issue 27: a cache that is data, not code ------------------------------------------------


class Planted:
    """What an attacker puts in a cache entry: unpickling it creates `marker`."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, tuple[Path]]:
        return Path.touch, (self.marker,)


def cli_answer(config: Path, folder: Path) -> str:
    """`dkreason match --json` in a fresh process (lark's tables are read at import)."""
    done = subprocess.run(
        [sys.executable, "-m", "dkreason.cli", "match", "--json", "--config", str(config), "X[b1]"],
        capture_output=True,
        text=True,
        env=os.environ | {"DKREASON_CACHE": str(folder), "PYTHONPATH": str(REPO / "src")},
    )
    assert done.returncode == 0 and not done.stderr, done.stderr
    return done.stdout


def test_a_planted_pickle_runs_nothing_and_changes_no_answer(
    tmp_path: Path, private_cache: Path
) -> None:
    config = write(Workload(30, 5, 5, 10, 5, nine()), tmp_path / "w")
    answer = cli_answer(config, private_cache)
    marker = tmp_path / "ran"
    entries = [p for p in private_cache.iterdir() if p.is_file()]
    for entry in entries:
        entry.write_bytes(pickle.dumps(Planted(marker)))
    for name in ("mtl.lark-cache", "sslt.lark-cache"):  # where lark kept its own tables
        (private_cache / name).write_bytes(pickle.dumps(Planted(marker)))
    assert cli_answer(config, private_cache) == answer
    assert not marker.exists()
    assert {p.name.split("-")[0] for p in entries} >= {"platform", "views", "lark"}


def test_a_planted_symlink_is_replaced_never_written_through(
    tmp_path: Path, private_cache: Path
) -> None:
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    answer = cli_answer(config, private_cache)
    victim = tmp_path / "victim"
    victim.write_text("precious")
    names = [p.name for p in private_cache.iterdir()] + ["mtl.lark-cache", "sslt.lark-cache"]
    for name in names:
        (private_cache / name).unlink(missing_ok=True)
        (private_cache / name).symlink_to(victim)
    assert cli_answer(config, private_cache) == answer
    assert victim.read_text() == "precious"
    assert all(
        not p.is_symlink() for p in private_cache.iterdir() if not p.name.endswith(".lark-cache")
    )


@pytest.mark.parametrize("mode", [0o777, 0o775])
def test_a_folder_others_can_write_is_refused_with_one_warning(
    tmp_path: Path, private_cache: Path, caplog: pytest.LogCaptureFixture, mode: int
) -> None:
    private_cache.mkdir()
    private_cache.chmod(mode)
    config = write(Workload(30, 5, 5, 0, 5, nine()), tmp_path / "w")
    answers = [KnowledgeManager.from_config(config).list_topics() for _ in range(2)]
    assert answers[0] == answers[1] and answers[0]
    (warning,) = caplog.records
    assert str(private_cache) in warning.getMessage() and "not used" in warning.getMessage()
    assert not list(private_cache.iterdir())


def test_a_folder_of_another_user_is_refused(
    tmp_path: Path, private_cache: Path, caplog: pytest.LogCaptureFixture
) -> None:
    private_cache.mkdir(mode=0o700)
    owner = private_cache.stat().st_uid
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "geteuid", lambda: owner + 1)  # as seen by someone else
        assert cache.folder() is None
    assert "owned by" in caplog.records[0].getMessage()


@pytest.mark.parametrize("device", ["fifo", "/dev/zero"])
def test_freshness_reads_through_the_input_door(
    tmp_path: Path, private_cache: Path, device: str
) -> None:
    """Once cached, an import replaced by a FIFO or a link to /dev/zero is refused at once,
    not waited on nor read until memory runs out."""
    from dkreason.errors import DkError

    from .test_owl import station

    config = station(tmp_path)
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2"]
    (tmp_path / "ssn.ttl").unlink()
    if device == "fifo":
        os.mkfifo(tmp_path / "ssn.ttl")
    else:
        (tmp_path / "ssn.ttl").symlink_to(device)
    with pytest.raises(DkError, match="ssn.ttl: not a regular file"):
        KnowledgeManager.from_config(config)


def test_a_catalog_that_appears_later_is_read(tmp_path: Path, private_cache: Path) -> None:
    from .test_owl import station

    config = station(tmp_path, platform='imports = "skip"')
    (tmp_path / "w.sslt").write_text("")
    catalog = (tmp_path / "catalog-v001.xml").read_bytes()
    (tmp_path / "catalog-v001.xml").unlink()
    assert "skipped" in KnowledgeManager.from_config(config).kb.warnings[0]
    (tmp_path / "catalog-v001.xml").write_bytes(catalog)
    assert KnowledgeManager.from_config(config).list_sort("System") == ["baro1", "baro2"]


def answers(config: Path) -> tuple[list[str], object]:
    km = KnowledgeManager.from_config(config)
    return km.list_topics(), km.check_formula(" and ".join(nine()))


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(kind=st.sampled_from(["platform", "views"]), where=st.floats(0, 1), bit=st.integers(0, 7))
def test_a_flipped_bit_gives_the_same_answer_as_no_cache(
    tmp_path_factory: pytest.TempPathFactory, kind: str, where: float, bit: int
) -> None:
    folder = tmp_path_factory.mktemp("flip")
    config = write(Workload(30, 5, 5, 10, 5, nine(), sort_share=0.8), folder / "w")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("DKREASON_CACHE", "off")
        truth = answers(config)
        patch.setenv("DKREASON_CACHE", str(folder / "cache"))
        assert answers(config) == truth
        (entry,) = (folder / "cache").glob(f"{kind}-*")
        data = bytearray(entry.read_bytes())
        data[int(where * (len(data) - 1))] ^= 1 << bit
        entry.write_bytes(bytes(data))
        assert answers(config) == truth


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(kind=st.sampled_from(["platform", "views"]), cut=st.floats(0, 1))
def test_a_foreign_pickle_after_any_prefix_of_an_entry_runs_nothing(
    tmp_path_factory: pytest.TempPathFactory, kind: str, cut: float
) -> None:
    folder = tmp_path_factory.mktemp("foreign")
    config = write(Workload(30, 5, 5, 0, 5, nine()), folder / "w")
    marker = folder / "ran"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("DKREASON_CACHE", str(folder / "cache"))
        truth = answers(config)
        (entry,) = (folder / "cache").glob(f"{kind}-*")
        data = entry.read_bytes()
        entry.write_bytes(data[: int(cut * len(data))] + pickle.dumps(Planted(marker)))
        assert answers(config) == truth
    assert not marker.exists()
