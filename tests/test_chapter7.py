"""The chapter 7 workloads (thesis 7.2) are ordinary files that load and match as the thesis
describes: one relevant topic per feature, irrelevant ones never chosen, quantified formulas
expanding to the same features as their written-out twins."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from benchmarks.chapter7.__main__ import CASES, main
from benchmarks.chapter7.workload import QUANTIFIED, Workload, expanded, formula, nine, write
from dkreason import KnowledgeManager

SMALL = Workload(concepts=30, relevant=5, irrelevant=20, relevant_specs=0, irrelevant_specs=15,
                 features=nine())


def test_a_workload_is_the_same_for_the_same_seed(tmp_path: Path) -> None:
    write(SMALL, tmp_path / "a")
    write(SMALL, tmp_path / "b")
    for name in ("ch7.owl", "ch7.sslt", "ch7.toml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_each_feature_of_the_nine_finds_exactly_its_relevant_topic(tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(write(SMALL, tmp_path))
    request = km.check_formula(formula(nine()))
    assert [[t.topic for t in f.topics] for f in request.features] == \
        [[f"rel{n}"] for n in range(9)]


@pytest.mark.parametrize("n", [3, 9, 27])
def test_a_quantified_formula_expands_to_its_written_out_twin(tmp_path: Path, n: int) -> None:
    w = Workload(50, 0, 41, 0, 0, expanded(27))
    km = KnowledgeManager.from_config(write(w, tmp_path))
    quantified = km.check_formula(QUANTIFIED[n])
    written = km.check_formula(formula(expanded(n)))
    assert sorted(f.feature.key for f in quantified.features) == \
        sorted(f.feature.key for f in written.features)
    assert all(len(f.topics) == 1 for f in quantified.features)


def test_every_test_case_point_builds_a_workload() -> None:
    for case in CASES:
        for i in range(len(case.xs)):
            w, text = case.point(i, 1)
            assert text and w.concepts >= 5
        assert all(len(v) == len(case.xs) for v in case.thesis.values())


def test_the_runner_rejects_an_unknown_test_case(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--cases", "9.9"]) == 2
    assert "unknown test case '9.9'" in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "says"), [
    (["--loads", "0"], "expected a whole number of at least 1, got '0'"),
    (["--growth", "--scales", "10,10"], "needs two different scales"),
])
def test_the_runner_rejects_bad_options_with_exit_2(
        capsys: pytest.CaptureFixture[str], argv: list[Any], says: str) -> None:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    assert code == 2 and says in capsys.readouterr().err
