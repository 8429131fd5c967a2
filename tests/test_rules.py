"""Rule files as a rule author writes them: the static checker (each mistake one line with
file:line:col), facts in rule files and tables, names as written, and a refused file that
leaves the engine as it was."""

from __future__ import annotations

from pathlib import Path

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.datalog import Datalog
from dkreason.errors import DkError, RuleError
from dkreason.policy.syntax import parse_rules
from dkreason.policy.tables import read_rule_file

from .conftest import SCENARIOS
from .test_federation import P1, P2


def own(scenario: Path, rules: str, base: str = "single.toml") -> Path:
    (scenario / "own.dl").write_text(rules, encoding="utf-8")
    config = scenario / "own.toml"
    config.write_text('rules = ["own.dl"]\n' + (scenario / base).read_text(encoding="utf-8"))
    return config


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[str]]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, (out.out + out.err).splitlines()


# ---- the shipped policy checks clean ---------------------------------------------------------


def test_the_shipped_policy_and_its_extension_check_clean() -> None:
    assert KnowledgeManager.check_rules() == []
    assert KnowledgeManager.check_rules(["rules/extensions/subsumption.dl"]) == []
    assert KnowledgeManager.check_rules(config=SCENARIOS / "federation.toml") == []
    strict = [
        "rules/ontology.dl",
        "rules/signature.dl",
        "rules/expansion.dl",
        "tests/data/strict.dl",
    ]
    assert KnowledgeManager.check_rules(strict, replace=True) == []


def test_rules_check_prints_nothing_but_its_count_for_a_clean_policy(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, lines = run(capsys, "rules", "check", "--config", str(SCENARIOS / "federation.toml"))
    assert (code, lines) == (0, ["0 errors, 0 warnings"])


# ---- each mistake of issue 29 (f): one line, with file:line:col -------------------------------

ERRORS = {
    "a variable only under negation": (
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & ~topic(P, T, Msg)\n",
        "own.dl:1:72: Msg in ~topic(…) is bound by no positive atom to its left: a negation "
        "only tests values already bound (name it _Msg if any value will do)",
    ),
    "an unbound head variable": (
        "veto(Q, P, T) <= topic(P, T, _M)\n",
        "own.dl:1:6: Q in the head of veto is bound by no positive atom of the body",
    ),
    "a variable only in a comparison": (
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & (X > 1)\n",
        "own.dl:1:60: X is compared in (X > 1) before anything binds it: bind it in a "
        "positive atom to the left",
    ),
    "a relation that negates itself": (
        ".decl odd(Platform)\nodd(P) <= platform(P) & ~odd(P)\n",
        "own.dl:2:25: negation cycle: odd reads ~odd (own.dl:2); a relation may not depend on "
        "its own negation",
    ),
    "a negation cycle through two rules": (
        ".decl a(P)\n.decl b(P)\na(P) <= platform(P) & ~b(P)\nb(P) <= platform(P) & a(P)\n"
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & a(P)\n",
        "own.dl:3:23: negation cycle: a reads ~b (own.dl:3), b reads a (own.dl:4); a relation "
        "may not depend on its own negation",
    ),
    "a misspelt relation": (
        "veto(Q, P, T) <= matched_topik(Q, P, T, _K, _A, _B, _C)\n",
        "own.dl:1:18: undeclared relation matched_topik/7 (did you mean matched_topic/7?)",
    ),
    "a wrong arity": (
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K)\n",
        "own.dl:1:18: matched_topic has 7 columns (Query, Platform, Topic, K, Arg1, Arg2, Arg3, "
        "declared at rules/schema.dl:",
    ),
    "a rule deriving an input": (
        "local(P) <= platform(P)\n",
        "own.dl:1:1: local is an input relation (declared at rules/schema.dl:",
    ),
    "a fact for what is given per formula": (
        "wanted(0, 'Speed', 'uav1', '', '')\n",
        "own.dl:1: wanted is given by dkreason while it asks a formula (declared at "
        "rules/schema.dl:",
    ),
    "a view reading what is given per formula": (
        ".decl asked(Query) view\nasked(Q) <= wanted(Q, _F, _A, _B, _C)\n",
        "own.dl:1: view asked reads wanted, which dkreason gives only while it asks a formula",
    ),
}


@pytest.mark.parametrize(("rules", "says"), ERRORS.values(), ids=list(ERRORS))
@pytest.mark.parametrize("command", ["match", "rules"])
def test_a_mistake_is_one_error_line_at_load_and_by_rules_check(
    capsys: pytest.CaptureFixture[str], scenario: Path, rules: str, says: str, command: str
) -> None:
    config = own(scenario, rules)
    argv = (
        ["match", "--config", str(config), "Altitude[uav1] > 1"]
        if command == "match"
        else ["rules", "check", "--config", str(config)]
    )
    code, lines = run(capsys, *argv)
    assert code == 2
    errors = [line for line in lines if line.startswith("error: ")]
    assert errors and errors[0].startswith(f"error: {says}"), lines
    if command == "match":
        assert lines == errors[:1]


WARNINGS = {
    "an unquoted constant": (
        "veto(Q, platform3, T) <= matched_topic(Q, platform3, T, _K, _A, _B, _C)\n",
        "own.dl:1:9: platform3 is a variable (its name starts with a lower-case letter); "
        "write 'platform3' for the constant",
    ),
    "a misspelt IRI": (
        f"veto(Q, P, T) <= matched_topic(Q, P, T, _K, '{P1}uav22', _B, _C)\n",
        f"own.dl:1:45: '{P1}uav22' occurs in no fact (did you mean "
        "'http://www.co-ode.org/ontologies/ont.owl#uav2'?)",
    ),
    "a misspelt name": (
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & topic(P, T, 'UavMgs')\n",
        "own.dl:1:71: 'UavMgs' occurs in no fact (did you mean 'UavMsg'?)",
    ),
    "a variable used once": (
        "veto(Q, P, T) <= matched_topic(Q, P, T, K, _A, _B, _C)\n",
        "own.dl:1:41: variable K occurs only once in the rule (name it _K if any value will do)",
    ),
    "a relation never derived": (
        ".decl unused(X)\nveto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & unused(P)\n",
        "own.dl:1: unused is declared, but no rule or fact derives it",
    ),
    "a relation never read": (
        ".decl unread(X)\nunread(P) <= platform(P)\n",
        "own.dl:1: unread is derived, but no rule reads it and dkreason does not ask it",
    ),
}


@pytest.mark.parametrize(("rules", "says"), WARNINGS.values(), ids=list(WARNINGS))
def test_a_suspect_rule_is_one_warning_line_and_the_run_goes_on(
    capsys: pytest.CaptureFixture[str], scenario: Path, rules: str, says: str
) -> None:
    config = own(scenario, rules)
    code = main(["match", "--config", str(config), "Altitude[uav1] > 1"])
    out = capsys.readouterr()
    assert code == 0
    assert out.err.splitlines() == [f"warning: {says}"]
    assert out.out.startswith("Feature: Altitude[uav1]\n")
    code, lines = run(capsys, "rules", "check", "--config", str(config))
    assert (code, lines) == (0, [f"warning: {says}", "0 errors, 1 warning"])


def test_an_unquoted_constant_is_a_variable_that_matches_anything(scenario: Path) -> None:
    km = KnowledgeManager.from_config(
        own(scenario, "veto(Q, platform3, T) <= matched_topic(Q, platform3, T, _K, _A, _B, _C)\n")
    )
    assert km.check_formula("Altitude[uav1] > 1").features[0].topics == ()


def test_rules_check_lists_every_error_of_files_without_a_config(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    (tmp_path / "bad.dl").write_text(
        "veto(Q, P, T) <= topic(P, T, _M)\n"
        "veto(Q, P, T) <= matched_topic(Q, P, T, _K, _A, _B, _C) & (X > 1)\n"
    )
    code, lines = run(capsys, "rules", "check", str(tmp_path / "bad.dl"))
    assert code == 2
    assert [line.split(": ")[1] for line in lines[:-1]] == [
        f"{tmp_path / 'bad.dl'}:1:6",
        f"{tmp_path / 'bad.dl'}:2:60",
    ]
    assert lines[-1] == "2 errors, 0 warnings"


# ---- facts in rule files and tables ----------------------------------------------------------


def test_facts_are_told_in_rule_files_and_tables(tmp_path: Path) -> None:
    (tmp_path / "t.dl").write_text(
        ".decl near(A, B)\n"
        "near('a', 1)\n"
        '.input near(filename="near.csv", headers=true)\n'
        ".input near\n"
    )
    (tmp_path / "near.csv").write_text('A,B\n"x, y",-2\nb,007\n')
    (tmp_path / "near.facts").write_text("c\t3\n")
    engine = Datalog()
    engine.load([read_rule_file(tmp_path / "t.dl", "t.dl")])
    assert sorted(engine.query("near", None, None), key=str) == [
        ("a", 1),
        ("b", "007"),
        ("c", 3),
        ("x, y", -2),
    ]
    assert str(engine.told[("near", "c", 3)]) == "near.facts:1"
    assert str(engine.told[("near", "b", "007")]) == "near.csv:3"


@pytest.mark.parametrize(
    ("table", "says"),
    [
        ("a,1,2\n", "near.csv:1: near has 2 columns (A, B, declared at t.dl:1), not 3"),
        (None, "t.dl:2: .input near: "),
    ],
)
def test_a_bad_table_is_one_line(tmp_path: Path, table: str | None, says: str) -> None:
    (tmp_path / "t.dl").write_text('.decl near(A, B)\n.input near(filename="near.csv")\n')
    if table is not None:
        (tmp_path / "near.csv").write_text(table)
    with pytest.raises(DkError) as raised:
        Datalog().load([read_rule_file(tmp_path / "t.dl", "t.dl")])
    assert str(raised.value).startswith(says)


def test_a_fact_holds_constants_only() -> None:
    with pytest.raises(RuleError, match=r"t\.dl:1:11: X is a variable, and a fact holds"):
        parse_rules("near('a', X)\n", "t.dl")


# ---- names as written ------------------------------------------------------------------------


def test_constants_may_be_local_prefixed_or_full_names(scenario: Path) -> None:
    for written in ("'Speed'", "'ontology:Speed'", f"'<{P1}Speed>'", f"'{P1}Speed'"):
        km = KnowledgeManager.from_config(
            own(
                scenario,
                f"veto(Q, P, T) <= matched_topic(Q, P, T, K, _A, _B, _C) "
                f"& topic_feature(P, T, K, {written}, _Field)\n",
            )
        )
        assert km.rule_warnings == []
        assert km.check_formula("Speed[uav1] > 1").features[0].topics == ()
        assert km.check_formula("Altitude[uav1] > 1").features[0].topics != ()


def test_a_name_two_platforms_give_different_iris_is_one_error(scenario: Path) -> None:
    with pytest.raises(DkError) as raised:
        KnowledgeManager.from_config(
            own(
                scenario,
                "veto(Q, P, T) <= matched_topic(Q, P, T, K, _A, _B, _C) "
                "& topic_feature(P, T, K, 'Speed', _Field)\n",
                "federation.toml",
            )
        )
    assert str(raised.value) == (
        f"own.dl:1:81: ambiguous name 'Speed': <{P1}Speed> (platform1) and <{P2}Speed> "
        "(platform2); write a prefixed name or a full <IRI>"
    )


# ---- a refused file leaves the engine as it was ----------------------------------------------


def test_a_refused_rule_file_leaves_the_engine_as_it_was() -> None:
    engine = Datalog()
    engine.load([parse_rules(".decl p(X) input\n.decl q(X)\nq(X) <= p(X)\n", "good.dl")])
    engine.assert_rows("p", [("a",)])
    before = (dict(engine.schema), list(engine.rules), engine.query("q", None))
    with pytest.raises(RuleError, match="bad.dl:3:16: negation cycle"):
        engine.load([parse_rules(".decl r(X)\nq(X) <= r(X)\nr(X) <= p(X) & ~q(X)\n", "bad.dl")])
    assert (engine.schema, engine.rules, engine.query("q", None)) == before
