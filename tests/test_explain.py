"""Explanations (why / why not), checked against the rules and the knowledge base."""

from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dkreason import DkError, KnowledgeManager
from dkreason.cli import main
from dkreason.explain import Failure, Proof, to_dot, to_json, to_text
from dkreason.parse.config import shipped_policy

from .conftest import REPO, SCENARIOS
from .test_expand import km as sea
from .test_federation import map_car3_to_a_truck

FORMULAS = {
    "F1": "□((Altitude[uav1] > Altitude[uav2]) and (Speed[uav1] > 50))",
    "F2": "for all x in UAV y in Car □(Altitude[x] > 10 and Speed[x] > Speed[y])",
    "F3": "for all x in UAV □(Close[uav1, x])",
}


@pytest.fixture(scope="module")
def federation() -> KnowledgeManager:
    assert SCENARIOS is not None
    return KnowledgeManager.from_config(SCENARIOS / "federation.toml")


def test_uastopic5_is_explained_by_the_bridge_the_remote_axiom_and_same_as(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert SCENARIOS is not None
    code = main(
        [
            "explain",
            "--config",
            str(SCENARIOS / "federation.toml"),
            "always (Altitude[uav2] > 10)",
            "--feature",
            "Altitude[uav2]",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    block = out[out.index("✔ uastopic5") :]
    summary = block.split("proof:")[0]
    assert "Altitude ≡ Height (bridge platform1→platform3, " in summary
    assert "platform1-platform3.cowl.xml:21)" in summary
    assert "≡ Alt (platform3 axiom, " in summary and "platform3.owl)" in summary
    assert "uav2 = uas21 (bridge platform1→platform3, " in summary
    assert "platform1-platform3.cowl.xml:29)" in summary


def test_a_sort_inherited_through_same_as_cites_the_member_told_so(tmp_path: Path) -> None:
    """contact3 (a Contact) is sameAs ship7 (a Ship): the sameAs class is a Vessel because of
    ship7's rdf:type, and the explanation says so rather than calling contact3 a Ship."""
    km = sea(tmp_path)
    e = km.explain("Heading[contact3] > 0")
    told = [
        leaf for w in e.features[0].why for leaf in w.proof.leaves() if leaf.fact[0] == "class_type"
    ]
    assert told and {leaf.text for leaf in told} == {
        "ship7 : Ship (sea axiom), in the sameAs class of contact3"
    }
    assert all((leaf.source or "").startswith("<http://sea.org/o#ship7> rdf:type") for leaf in told)
    lines = {line for w in e.features[0].why for line in w.summary}
    assert (
        f"argument 1 of track: ship7 : Ship ⊑ Vessel (sea axiom, {tmp_path / 'sea.ttl'})" in lines
    )


def test_why_not_a_topic_whose_argument_names_another_object(federation: KnowledgeManager) -> None:
    e = federation.explain(FORMULAS["F3"], feature="Close[uav1, uav1]", topic="uastopic7")
    (why_not,) = e.features[0].why_not
    check_failure(federation, why_not.trace)
    assert why_not.platform == "platform3"
    assert "argument 2 is uas21" in why_not.reason and "not uas20" in why_not.reason
    assert "Close[uav1, uav1] maps to Near[uas20, uas20]" in why_not.reason


def test_why_not_a_platform_where_the_object_has_no_counterpart(
    federation: KnowledgeManager,
) -> None:
    e = federation.explain("always (Speed[car3] > 60)", topic="carstopic1")
    (why_not,) = e.features[0].why_not
    check_failure(federation, why_not.trace)
    assert why_not.platform == "platform2"
    assert "car3 has no counterpart on platform2" in why_not.reason


def test_why_not_a_local_equivalent_with_another_signature(federation: KnowledgeManager) -> None:
    e = federation.explain("always (Speed[car1] > 60)", topic="topic9")
    reasons = [w.reason for w in e.features[0].why_not]
    assert "GroundSpeed[car1] rejected: car1 is a Car, GroundSpeed needs UAV" in reasons


def test_why_not_a_mis_mapping_into_the_wrong_sort(scenario: Path) -> None:
    map_car3_to_a_truck(scenario)
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    e = km.explain("always (Speed[car3] > 60)", topic="carstopic1")
    (why_not,) = e.features[0].why_not
    assert why_not.reason == (
        "Speed[truck1] rejected: truck1 is a GroundVehicle, Speed needs Automobile"
    )


def test_why_not_looks_on_every_platform_of_the_context(federation: KnowledgeManager) -> None:
    """No topic carries Position[uav1]: each platform the local one reaches is checked once
    (platform 2 and 3 too, not platform 1 once per context)."""
    e = federation.explain("always (Position[uav1] > 0)")
    why_not = e.features[0].why_not
    assert sorted(w.platform for w in why_not) == ["platform1", "platform2", "platform3"]
    (on_cars,) = [w for w in why_not if w.platform == "platform2"]
    assert "uav1 has no counterpart on platform2" in on_cars.reason


def test_a_rule_from_an_extension_file_is_cited_with_its_file_and_line(scenario: Path) -> None:
    extension = scenario / "alias.dl"
    extension.write_text(
        "# my policy: Altitude also reads Size topics\n"
        ".decl alias(Feature, Other)\n"
        "feature_candidate(L, F, G) <= local(L) & feature(L, F, _N) & "
        "feature(L, G, _M) & alias(F, G)\n"
        "alias('http://www.example.com/ontology#Altitude', "
        "'http://www.example.com/ontology#Size') <= local(_L)\n"
    )
    with (scenario / "specs" / "platform1.sslt").open("a") as specs:
        specs.write("topic topic10:UavMsg contains Size(uav1) = msg.size for uav1 = msg.id\n")
    config = scenario / "single.toml"
    config.write_text('rules = ["alias.dl"]\n' + config.read_text())
    e = KnowledgeManager.from_config(config).explain("Altitude[uav1] > 1", topic="topic10")
    (why,) = e.features[0].why
    cited = {str(p.rule.span) for p in _nodes(why.proof) if p.rule}
    assert any(c.endswith(f"{extension.name}:3") for c in cited), cited


def _nodes(p: Proof) -> Iterator[Proof]:
    yield p
    for c in p.children:
        yield from _nodes(c)


# ---- the mechanical check: leaves are told facts, inner steps are instances of rules --------


def _rule_at(file: str, line: int) -> ast.Compare:
    text = Path(file).read_text(encoding="utf-8")  # `.decl` lines blanked, numbers kept
    tree = ast.parse(re.sub(r"(?m)^\.decl\b.*$", "", text))
    (stmt,) = [s for s in tree.body if s.lineno == line]
    assert isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Compare)
    return stmt.value


def _flatten(node: ast.expr) -> list[ast.expr]:
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
        return _flatten(node.left) + _flatten(node.right)
    return [node]


def _match(terms: list[ast.expr], values: tuple[Any, ...], env: dict[str, Any]) -> bool:
    if len(terms) != len(values):
        return False
    for term, value in zip(terms, values, strict=True):
        if isinstance(term, ast.Name):
            if env.setdefault(term.id, value) != value:
                return False
        elif not (isinstance(term, ast.Constant) and term.value == value):
            return False
    return True


def check_proof(km: KnowledgeManager, p: Proof, derived: set[str]) -> int:
    """Assert `p` is sound; return the number of steps checked."""
    engine = km.kb.engine
    if p.rule is None:
        kind = p.fact[0]
        if kind == "compare":
            return 1
        if kind == "not":
            assert not engine.query(str(p.fact[1]), *p.fact[2:]), p.text
            return 1
        assert kind not in derived, f"leaf {p.fact} is a derived relation"
        assert engine.query(str(kind), *p.fact[1:]), f"leaf {p.fact} is not in the knowledge base"
        return 1
    clause = _rule_at(p.rule.span.file, p.rule.span.line)
    head = clause.left
    assert isinstance(head, ast.Call) and isinstance(head.func, ast.Name)
    env: dict[str, Any] = {}
    assert head.func.id == p.fact[0] and _match(head.args, p.fact[1:], env), p.text
    body = _flatten(clause.comparators[0])
    assert len(body) == len(p.children), p.text
    for item, child in zip(body, p.children, strict=True):
        if isinstance(item, ast.UnaryOp):  # negation
            call = item.operand
            assert isinstance(call, ast.Call) and isinstance(call.func, ast.Name)
            assert child.fact[:2] == ("not", call.func.id)
            assert _match(call.args, child.fact[2:], env)
        elif isinstance(item, ast.Compare):
            assert child.fact[0] == "compare"
        else:
            assert isinstance(item, ast.Call) and isinstance(item.func, ast.Name)
            assert child.fact[0] == item.func.id, child.text
            assert _match(item.args, child.fact[1:], env), f"{child.text} ≠ {ast.unparse(item)}"
    return 1 + sum(check_proof(km, c, derived) for c in p.children)


def check_failure(km: KnowledgeManager, f: Failure) -> None:
    """Every goal on a why-not trace really fails (goals mentioning the formula's own
    `wanted` facts are checked by the callers' expectations instead)."""
    if "wanted" not in str(f.rule.text if f.rule else ""):
        assert not km.kb.engine.query(str(f.goal[0]), *f.goal[1:]), f.text
    if isinstance(f.because, Failure):
        check_failure(km, f.because)


@pytest.mark.parametrize("config", ["single.toml", "federation.toml"])
@pytest.mark.parametrize("name", list(FORMULAS))
def test_every_explanation_tree_is_made_of_told_facts_and_rule_instances(
    config: str, name: str
) -> None:
    assert SCENARIOS is not None
    km = KnowledgeManager.from_config(SCENARIOS / config)
    request = km.check_formula(FORMULAS[name])
    e = km.explain(FORMULAS[name])
    derived = {r.head.predicate for r in km.kb.engine.rules}
    proofs = [w for f in e.features for w in f.why]
    assert len(proofs) == sum(len(f.topics) for f in request.features)
    wanted: list[tuple[str | int, ...]] = [
        (q, g.feature.iri, *g.feature.arg_iris, *[""] * (3 - len(g.feature.arg_iris)))
        for q, g in enumerate(request.features)
    ]
    km.kb.engine.assert_rows("wanted", wanted)  # the formula's facts, as during explanation
    try:
        steps = sum(check_proof(km, w.proof, derived) for w in proofs)
    finally:
        km.kb.engine.retract_rows("wanted", wanted)
    assert steps > 20 * len(proofs)


def test_json_and_dot_forms(federation: KnowledgeManager) -> None:
    e = federation.explain("always (Altitude[uav2] > 10)")
    data = json.loads(json.dumps(to_json(e)))
    why = data["features"][0]["why"]
    assert {w["topic"] for w in why} == {"topic2", "uastopic5"}
    assert why[0]["proof"]["rule"].startswith("rules/matching.dl:")
    dot = to_dot(e)
    assert dot.startswith("digraph explanation {") and dot.rstrip().endswith("}")


def test_unknown_feature_or_topic_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert SCENARIOS is not None
    for extra in (["--feature", "Altitude[uav9]"], ["--topic", "nope"]):
        code = main(
            [
                "explain",
                "--config",
                str(SCENARIOS / "federation.toml"),
                "Altitude[uav2] > 1",
                *extra,
            ]
        )
        out = capsys.readouterr()
        assert code == 2 and (out.out + out.err).count("\n") == 1


def test_the_docs_explain_example_is_what_the_command_prints(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The docs show `dkreason explain` citing rule lines: they follow the rule files."""
    readme = (REPO / "docs" / "explanations.md").read_text(encoding="utf-8")
    command = '$ dkreason explain --config examples/federation.toml "always (Altitude[uav2] > 10)"'
    block = readme[readme.index(command) :].split("```")[0].splitlines()[1:]
    monkeypatch.chdir(REPO)
    assert (
        main(
            [
                "explain",
                "--config",
                "examples/federation.toml",
                "always (Altitude[uav2] > 10)",
                "--feature",
                "Altitude[uav2]",
                "--proof",  # the docs' block shows the proof's first lines
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out.splitlines()
    shown = [line for line in block if line.strip() and line.strip() != "..."]
    assert len(shown) > 5 and all(line in printed for line in shown)


def test_an_explanation_is_the_same_in_every_process() -> None:
    """String hashes differ per process, and with them the order of the engine's answers;
    the proofs and failures an explanation picks must not."""
    assert SCENARIOS is not None
    outs = {
        subprocess.run(
            [
                sys.executable,
                "-m",
                "dkreason.cli",
                "explain",
                "--config",
                str(SCENARIOS / "federation.toml"),
                FORMULAS["F3"],
                "--feature",
                "Close[uav1, uav1]",
                "--topic",
                "uastopic7",
            ],
            capture_output=True,
            text=True,
            check=True,
            env=os.environ | {"PYTHONHASHSEED": seed, "DKREASON_CACHE": "off"},
        ).stdout
        for seed in ("1", "2", "3")
    }
    assert len(outs) == 1 and "argument 2 is uas21" in next(iter(outs))


# ---- a policy of one's own: explain reads only what the schema makes every policy derive -------


def renamed_candidate(scenario: Path) -> Path:
    """A replacing policy: the shipped rules, with `candidate` renamed `reading` (declared and
    derived under its new name), so nothing derives the `candidate` explain walks."""
    policy = scenario / "policy"
    policy.mkdir()
    for path in shipped_policy():
        text = re.sub(r"\bcandidate\(", "reading(", path.read_text(encoding="utf-8"))
        (policy / path.name).write_text(text, encoding="utf-8")
    with (policy / "matching.dl").open("a", encoding="utf-8") as rules:
        rules.write(".decl reading(Query, Platform, LocalFeature, Feature, Arg1, Arg2, Arg3)\n")
    config = scenario / "renamed.toml"
    files = ", ".join(f'"policy/{path.name}"' for path in shipped_policy())
    config.write_text(
        f"replace_rules = true\nrules = [{files}]\n"
        + (scenario / "federation.toml").read_text(encoding="utf-8")
    )
    return config


def test_a_policy_that_derives_no_candidate_is_refused_at_load(scenario: Path) -> None:
    with pytest.raises(
        DkError, match=r"schema\.dl:\d+: the rules derive no candidate/7, which dkreason asks for"
    ):
        KnowledgeManager.from_config(renamed_candidate(scenario))


@pytest.mark.parametrize("command", ["explain", "match"])
def test_a_policy_that_derives_no_candidate_is_one_error_line(
    capsys: pytest.CaptureFixture[str], scenario: Path, command: str
) -> None:
    config = renamed_candidate(scenario)
    code = main([command, "--config", str(config), "always (Position[uav1] > 0)"])
    out = capsys.readouterr()
    assert code == 2
    (line,) = (out.out + out.err).splitlines()
    assert re.fullmatch(r"error: \S*schema\.dl:\d+: the rules derive no candidate/7, .*", line)


ODD_POLICIES = {
    "relevant_topic from a fact": "relevant_topic(Q, P, 'topic3', 1, O1, 'odd', '', 3, '', '') "
    "<= wanted(Q, _F, O1, '', '') & local(P)\n",
    "a topic answered without relevant_topic": "match_result(Q, 'topic', P, 'topic3', 1, O1, "
    "'', '', 3, '', '') <= wanted(Q, _F, O1, '', '') & local(P)\n",
    "a matched topic without relevant_topic": "matched_topic(Q, P, 'topic1', 9, C1, C2, C3) "
    "<= sound_candidate(Q, P, G, C1, C2, C3) & feature(P, G, _Arity)\n",
}


def with_rules(scenario: Path, rules: str) -> KnowledgeManager:
    """The single-platform scenario with the shipped policy and these rules besides."""
    (scenario / "odd.dl").write_text(rules, encoding="utf-8")
    config = scenario / "single.toml"
    config.write_text('rules = ["odd.dl"]\n' + config.read_text(encoding="utf-8"))
    return KnowledgeManager.from_config(config)


@pytest.mark.parametrize("rules", ODD_POLICIES.values(), ids=list(ODD_POLICIES))
def test_a_policy_that_loads_is_explained_and_rendered_whatever_it_derives(
    scenario: Path, rules: str
) -> None:
    km = with_rules(scenario, rules)
    for topic in (None, "topic1", "topic3"):
        e = km.explain("always (Speed[uav2] > 1)", topic=topic)
        assert to_text(e) and to_dot(e) and json.dumps(to_json(e), ensure_ascii=False)


def test_a_derivation_deeper_than_a_replay_goes_is_shown_as_the_answer_itself(
    scenario: Path,
) -> None:
    steps = range(1, 50)
    km = with_rules(
        scenario,
        ".decl step0(Query, Object)\n"
        + "".join(f".decl step{i}(Query, Object)\n" for i in steps)
        + "step0(Q, O) <= wanted(Q, _F, O, '', '')\n"
        + "".join(f"step{i}(Q, O) <= step{i - 1}(Q, O)\n" for i in steps)
        + "relevant_topic(Q, P, 'topic3', 1, O, '', '', 3, '', '') <= step49(Q, O) & local(P)\n",
    )
    (why,) = km.explain("always (Speed[uav2] > 1)", topic="topic3").features[0].why
    assert why.proof.rule is None and why.proof.children == ()
    assert why.proof.text == "relevant_topic(0, platform1, topic3, 1, uav2, –, –, 3, –, –)"
    assert why.proof.source == "the policy answers it; no proof of at most 40 steps replays it"


def test_a_relation_of_a_policy_s_own_is_not_read_as_the_shipped_one_of_that_name(
    scenario: Path,
) -> None:
    """Explanations word `excluded` as an incompat bridge: not this policy's excluded/2."""
    strict = (REPO / "tests" / "data" / "strict.dl").read_text(encoding="utf-8")
    sound = "sound_candidate(Q, P, G, O1, O2, O3) <= candidate(Q, P, _F, G, O1, O2, O3)"
    assert sound in strict
    (scenario / "own.dl").write_text(
        strict.replace(sound, f"{sound} & ~excluded(P, G)")
        + ".decl excluded(Platform, Feature)\n"
        + "excluded(P, F) <= local(P) & feature(P, F, 1)\n",
        encoding="utf-8",
    )
    config = scenario / "own.toml"
    config.write_text(
        'replace_rules = true\nrules = ["rules/ontology.dl", "rules/signature.dl", '
        '"rules/expansion.dl", "own.dl"]\n' + (scenario / "single.toml").read_text()
    )
    e = KnowledgeManager.from_config(config).explain("always (Speed[uav2] > 1)")
    (why_not,) = e.features[0].why_not
    assert why_not.reason == "Speed[uav2] rejected: excluded(platform1, Speed) holds [own.dl:12]"


UNDECLARED_ANSWERS = {
    "a topic no spec declares": "'nowhere', 1",
    "a feature the topic does not have": "'topic3', 2",
    "a topic feature of another arity": "'topic6', 1",
}


@pytest.mark.parametrize("command", ["explain", "match"])
@pytest.mark.parametrize("answer", UNDECLARED_ANSWERS.values(), ids=list(UNDECLARED_ANSWERS))
def test_a_policy_answering_with_no_declared_topic_feature_is_one_error_line(
    capsys: pytest.CaptureFixture[str], scenario: Path, answer: str, command: str
) -> None:
    (scenario / "odd.dl").write_text(
        f"relevant_topic(Q, P, {answer}, O1, '', '', 1, '', '') "
        "<= wanted(Q, _F, O1, '', '') & local(P)\n",
        encoding="utf-8",
    )
    config = scenario / "single.toml"
    config.write_text('rules = ["odd.dl"]\n' + config.read_text(encoding="utf-8"))
    code = main([command, "--config", str(config), "always (Speed[uav2] > 1)"])
    out = capsys.readouterr()
    assert code == 2
    # the checker's warning about a topic no fact names, and the one error line
    *warnings, line = (out.out + out.err).splitlines()
    topic, k = (part.strip(" '") for part in answer.split(","))
    assert warnings == (
        ["warning: odd.dl:1:22: 'nowhere' occurs in no fact"] if topic == "nowhere" else []
    )
    assert line == (
        f"error: the policy answers Speed[uav2] with feature {k} of topic {topic} on "
        "platform1, which no topic specification there declares with 1 argument"
    )


# ---- the answer first; the proof with --proof, each shared subtree once -------------------------


def explain_text(capsys: pytest.CaptureFixture[str], *extra: str) -> list[str]:
    assert SCENARIOS is not None
    code = main(
        [
            "explain",
            "--config",
            str(SCENARIOS / "federation.toml"),
            "always (Altitude[uav2] > 10)",
            *extra,
        ]
    )
    assert code == 0
    return capsys.readouterr().out.splitlines()


def test_the_answer_comes_first_and_the_proof_with_proof(
    capsys: pytest.CaptureFixture[str],
) -> None:
    plain = explain_text(capsys)
    assert plain[0] == "Altitude[uav2]"
    assert [line for line in plain if line.startswith("  ✔")] == [
        "  ✔ uastopic5 on platform3 (msg.id = 21)",
        "  ✔ topic2 on platform1 (msg.id = 2)",
    ]
    assert all(line.startswith(("  ✔", "      ")) for line in plain[1:])
    assert "      proof:" not in plain
    proved = explain_text(capsys, "--proof")
    assert [line for line in proved if not line.startswith("        ")] == [
        *[line for line in plain if "proof:" not in line][:5],
        "      proof:",
        *[line for line in plain if "proof:" not in line][5:],
        "      proof:",
    ]


def test_a_subtree_shown_twice_is_printed_once_and_referred_to(
    capsys: pytest.CaptureFixture[str],
) -> None:
    lines = explain_text(capsys, "--proof")
    numbered = {m.group(1): line for line in lines if (m := re.search(r"  #(\d+)$", line))}
    referred = [m.group(1) for line in lines if (m := re.search(r"\(as #(\d+) above\)$", line))]
    assert numbered and set(referred) == set(numbered)
    for number, line in numbered.items():  # the reference names the same fact, printed before
        fact = line.strip().split("  ")[0]
        first = lines.index(line)
        assert all(
            lines.index(ref) > first
            for ref in lines
            if ref.strip() == f"{fact}  (as #{number} above)"
        )


def test_depth_cuts_each_proof_tree(capsys: pytest.CaptureFixture[str]) -> None:
    lines = explain_text(capsys, "--depth", "2")
    assert "      proof:" in lines
    proof = [line for line in lines if line.startswith("        ")]
    facts = [line for line in proof if not line.strip().startswith("… ")]
    assert max(len(line) - len(line.lstrip()) for line in facts) == 10  # the root, its children
    assert any(line.strip().endswith("more below depth 2") for line in proof)


def test_rule_files_are_cited_relative_to_the_config_wherever_dkreason_runs(
    scenario: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (scenario / "policies").mkdir()
    (scenario / "policies" / "own.dl").write_text(
        "veto(Q, 'platform3', T) <= wanted(Q, _F, _O1, _O2, _O3) & topic('platform3', T, _M)\n"
    )
    config = scenario / "own.toml"
    config.write_text('rules = ["policies/own.dl"]\n' + (scenario / "federation.toml").read_text())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    e = KnowledgeManager.from_config(config).explain(FORMULAS["F1"], topic="uastopic5")
    (why_not,) = [n for n in e.features[1].why_not if "veto" in n.reason]
    assert "[policies/own.dl:1]" in why_not.reason
    (why,) = KnowledgeManager.from_config(config).explain(FORMULAS["F1"]).features[1].why
    assert str(why.proof.rule.span if why.proof.rule else "") == "rules/matching.dl:95"
