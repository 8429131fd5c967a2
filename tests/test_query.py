"""`dkreason query`: questions to a loaded knowledge base in the rules' own language."""

from __future__ import annotations

import json
import re

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main

from .conftest import SCENARIOS
from .test_federation import ONT, P3


@pytest.fixture(scope="module")
def federation() -> KnowledgeManager:
    return KnowledgeManager.from_config(SCENARIOS / "federation.toml")


def ask(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    code = main(["query", "--config", str(SCENARIOS / "federation.toml"), *argv])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out


def test_which_objects_are_same_as_uav2(capsys: pytest.CaptureFixture[str]) -> None:
    """uav2 read on every platform: itself, and uas21 through the 'same' bridge rule."""
    assert ask(capsys, "arg_candidate(P, 'uav2', O)").splitlines() == [
        "P          O",
        "platform1  uav2",
        "platform3  uas21",
    ]
    assert json.loads(ask(capsys, "--json", "arg_candidate(P, 'uav2', O)")) == [
        {"P": "platform1", "O": ONT + "uav2"},
        {"P": "platform3", "O": P3 + "uas21"},
    ]


def test_which_topics_carry_any_feature_of_uav1(capsys: pytest.CaptureFixture[str]) -> None:
    """The design card's relevant_topic(Feature, Args, Topic, Filter), the arguments and the
    filter as tuples."""
    out = ask(capsys, "relevant_topic(F, ('uav1',), T, Filter)")
    assert out.splitlines() == [
        "F            T          Filter",
        "GroundSpeed  topic1     (1)",
        "GroundSpeed  uastopic1  (20)",
        "GroundSpeed  uastopic2  (20)",
        "Altitude     topic1     (1)",
        "Altitude     topic2     (1)",
        "Altitude     uastopic4  (20)",
        "Speed        topic1     (1)",
        "Speed        uastopic1  (20)",
        "Speed        uastopic2  (20)",
    ]


def test_the_readers_relevant_topic_is_what_match_finds(federation: KnowledgeManager) -> None:
    formula = "Close[uav1, uav2] > 0"
    answer = federation.query("relevant_topic('Close', ['uav1', 'uav2'], T, _Filter)")
    (feature,) = federation.check_formula(formula).features
    assert answer.columns == ("T",)
    assert sorted(t for (t,) in answer.rows) == sorted(t.topic for t in feature.topics)


def test_a_question_of_several_conditions(federation: KnowledgeManager) -> None:
    answer = federation.query(
        "topic_arg(P, T, _K, 1, 'object', O, _Id) & ~topic_arg(P, T, _K2, 2, _Kind, _E, _I2) "
        "& (P != 'platform1')"
    )
    assert answer.columns == ("P", "T", "O")
    assert ("platform3", "uastopic5", P3 + "uas21") in answer.rows
    assert all(p != "platform1" for p, _, _ in answer.rows)


@pytest.mark.parametrize("written", ["'uas21'", "'distributed_uavs:uas21'", f"'<{P3}uas21>'"])
def test_constants_are_written_as_in_rule_files(federation: KnowledgeManager, written: str) -> None:
    answer = federation.query(f"topic_arg(_P, T, _K, _I, 'object', {written}, _Id)")
    assert sorted(answer.rows) == [("uastopic5",), ("uastopic7",), ("uastopic8",)]


def test_a_question_without_variables_is_yes_or_no(capsys: pytest.CaptureFixture[str]) -> None:
    assert ask(capsys, "context('platform1', 'platform3')") == "yes\n"
    assert ask(capsys, "context('platform1', 'nowhere')") == "no\n"


@pytest.mark.parametrize(
    ("question", "says"),
    [
        ("same_as(P, O, uav2)", "uav2 is a variable (variables start with an upper-case"),
        ("same_az(P, O, 'uav2')", "<query>:1:1: undeclared relation same_az/3 (did you mean "),
        ("same_as(P, O)", "<query>:1:1: same_as has 3 columns (Platform, Object, Other, declared"),
        (
            "sort_match(R, G, I, A, B, C, T, K)",
            "cannot ask sort_match(R, G, I, A, B, C, T, K): C2 is compared in (C2 != '') before "
            "anything binds it",
        ),
        ("topic(P, T, _M) & (X > 1)", "cannot ask topic(P, T, _M) & (X > 1): X is compared"),
        ("relevant_topic(F, 'uav1', T, Filter)", "relevant_topic's Args is a tuple"),
        ("same_as(P, O, ", "<query>:1:"),
    ],
)
def test_a_bad_question_is_one_error_line(
    capsys: pytest.CaptureFixture[str], question: str, says: str
) -> None:
    code = main(["query", "--config", str(SCENARIOS / "federation.toml"), question])
    out = capsys.readouterr()
    assert code == 2
    (line,) = (out.out + out.err).splitlines()
    assert line.startswith(f"error: {says}"), line


def test_relations_lists_every_relation_with_its_columns_kind_and_rows(
    capsys: pytest.CaptureFixture[str], federation: KnowledgeManager
) -> None:
    lines = ask(capsys, "--relations").splitlines()
    assert lines[0].split() == ["relation", "kind", "rows"]
    rows = {
        found.group(1): (found.group(2), found.group(3))
        for line in lines[1:]
        if (found := re.fullmatch(r"(\w+)\(.*?\)\s+(\S+)\s+(.*)", line))
    }
    assert rows["local"] == ("input", "1")
    assert rows["wanted"] == ("given", "– (given while a formula is asked)")
    assert rows["candidate"] == ("query", "– (per formula: reads wanted)")
    assert rows["context"] == ("query", "3")
    assert rows["sort_match"] == ("derived", "– (asked with some arguments bound)")
    assert lines[-1].split("  ")[0] == "relevant_topic(Feature, Args, Topic, Filter)"
    listed = {r.relation.name for r in federation.relations()}
    assert listed == set(federation.kb.engine.schema)
    data = json.loads(ask(capsys, "--relations", "--json"))
    (feature,) = [r for r in data if r["relation"] == "feature"]
    assert feature == {
        "relation": "feature",
        "columns": ["Platform", "Feature", "Arity"],
        "kind": "input",
        "rows": 18,
        "note": "",
    }


def test_a_question_or_relations_is_asked(capsys: pytest.CaptureFixture[str]) -> None:
    for extra in ([], ["--relations", "local(P)"]):
        code = main(["query", "--config", str(SCENARIOS / "federation.toml"), *extra])
        assert code == 2 and capsys.readouterr().err == "error: give a query, or --relations\n"
