"""The chapter 7 workloads (thesis 7.2) are ordinary files that load and match as the thesis
describes: one relevant topic per feature, irrelevant ones never chosen, quantified formulas
expanding to the same features as their written-out twins."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.workloads import COLUMNS, QUANTIFIED, SETUPS, Workload, expanded, formula, nine, write

SMALL = Workload(
    concepts=30, relevant=5, irrelevant=20, relevant_specs=0, irrelevant_specs=15, features=nine()
)


def test_a_workload_is_the_same_for_the_same_seed(tmp_path: Path) -> None:
    write(SMALL, tmp_path / "a")
    write(SMALL, tmp_path / "b")
    for name in ("ch7.owl", "ch7.sslt", "ch7.toml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_each_feature_of_the_nine_finds_exactly_its_relevant_topic(tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(write(SMALL, tmp_path))
    request = km.check_formula(formula(nine()))
    assert [[t.topic for t in f.topics] for f in request.features] == [
        [f"rel{n}"] for n in range(9)
    ]


@pytest.mark.parametrize("n", [3, 9, 27])
def test_a_quantified_formula_expands_to_its_written_out_twin(tmp_path: Path, n: int) -> None:
    w = Workload(50, 0, 41, 0, 0, expanded(27))
    km = KnowledgeManager.from_config(write(w, tmp_path))
    quantified = km.check_formula(QUANTIFIED[n])
    written = km.check_formula(formula(expanded(n)))
    assert sorted(f.feature.key for f in quantified.features) == sorted(
        f.feature.key for f in written.features
    )
    assert all(len(f.topics) == 1 for f in quantified.features)


def test_every_test_case_point_builds_a_workload() -> None:
    for name, setup in SETUPS.items():
        for i in range(COLUMNS[name]):
            w, text = setup(i, 1)
            assert text and w.concepts >= 5


ANSWERS = Path(__file__).parent / "data" / "chapter7" / "answers.json"


def _points() -> list[tuple[str, int, float]]:
    return [
        (case, i, share)
        for case, columns in COLUMNS.items()
        for i in (0, columns - 1)
        for share in (0.0, 0.8)
    ]


@pytest.mark.parametrize(("case", "point", "share"), _points())
def test_symbolic_sorts_give_the_answers_of_materialized_ones(
    tmp_path: Path, case: str, point: int, share: float
) -> None:
    """Differential: every seeded chapter 7 workload, as the thesis writes it (share 0) and
    with 80% of the further relevant specs over `some B`, matches exactly the topics and
    filters the matcher gave when sort arguments were materialized per object
    (tests/data/chapter7/answers.json, recorded with that matcher)."""
    w, text = SETUPS[case](point, 1)
    w = replace(w, sort_share=share, relevant_specs=max(w.relevant_specs, 20))
    request = KnowledgeManager.from_config(write(w, tmp_path)).check_formula(text)
    got = {
        str(f.feature.key): sorted([t.topic, sorted(map(list, t.filter))] for t in f.topics)
        for f in request.features
    }
    assert got == json.loads(ANSWERS.read_text(encoding="utf-8"))[f"{case}/{point}/{share}"]
