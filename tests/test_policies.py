"""Policies a rule author writes (issue 29, a–e), each a few lines in a rule file of its own on
the shipped policy's hooks: checked with `match`, `explain` and the golden-file runner."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import MissingIdError
from dkreason.explain import render, to_json

from .test_federation import P1, drop_rule


def policy(scenario: Path, rules: str, base: str = "federation.toml") -> Path:
    """The scenario's config with the shipped policy and `rules` (own.dl) besides."""
    (scenario / "own.dl").write_text(rules, encoding="utf-8")
    config = scenario / f"own-{base}"
    config.write_text('rules = ["own.dl"]\n' + (scenario / base).read_text(encoding="utf-8"))
    return config


def topics(km: KnowledgeManager, formula: str) -> list[tuple[str, str]]:
    (feature,) = km.check_formula(formula).features
    return [(t.platform, t.topic) for t in feature.topics]


def golden(
    capsys: pytest.CaptureFixture[str], folder: Path, config: Path, case: dict[str, Any]
) -> str:
    """`dkreason test` on one case of this config: its output (exit 0 expected)."""
    folder.mkdir(exist_ok=True)
    (folder / "case.json").write_text(
        json.dumps({"config": f"../{config.name}", **case}), encoding="utf-8"
    )
    code = main(["test", str(folder)])
    out = capsys.readouterr().out
    assert code == 0, out
    return out


def all_explained(km: KnowledgeManager, formula: str, topic: str | None = None) -> str:
    """Every form of the explanation, rendered: none may raise."""
    e = km.explain(formula, topic=topic)
    json.dumps(to_json(e), ensure_ascii=False)
    render(e, "dot")
    return render(e, "text", proof=True)


# ---- a. never use platform3's topics ----------------------------------------------------------

NEVER_PLATFORM3 = (
    "veto(Q, 'platform3', T) <= wanted(Q, _F, _O1, _O2, _O3) & topic('platform3', T, _M)\n"
)


def test_a_never_using_a_platform_is_one_veto(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    km = KnowledgeManager.from_config(policy(scenario, NEVER_PLATFORM3))
    assert km.rule_warnings == []
    assert topics(km, "always (Altitude[uav2] > 10)") == [("platform1", "topic2")]
    e = km.explain("always (Altitude[uav2] > 10)", topic="uastopic5")
    assert [n.reason for n in e.features[0].why_not] == [
        "veto(0, platform3, uastopic5) holds [own.dl:1]; Altitude[uav2] maps to Alt[uas21] "
        "on platform3",
        "uastopic5 carries Alt, not Height; Altitude[uav2] maps to Height[uas21] on platform3",
    ]
    out = golden(
        capsys,
        scenario / "golden",
        scenario / "own-federation.toml",
        {
            "match": "always (Altitude[uav2] > 10)",
            "expect": {
                "formula": "always (Altitude[uav2] > 10)",
                "features": [
                    {
                        "feature": "Altitude",
                        "args": ["uav2"],
                        "topics": [
                            {
                                "platform": "platform1",
                                "topic": "topic2",
                                "msgtype": "UavMsg",
                                "field": "msg.alt",
                                "filter": {"msg.id": 2},
                            }
                        ],
                    }
                ],
            },
        },
    )
    assert out.splitlines()[-1] == "1 passed, 0 failed"


# ---- b. prefer local topics: a remote one only when no local topic carries the feature ----

PREFER_LOCAL = (
    "veto(Q, R, T) <= matched_topic(Q, R, T, _K, _C1, _C2, _C3) & ~local(R) & local(L) "
    "& matched_topic(Q, L, _T, _K2, _D1, _D2, _D3)\n"
)


def test_b_preferring_local_topics_is_one_veto(scenario: Path) -> None:
    km = KnowledgeManager.from_config(policy(scenario, PREFER_LOCAL))
    assert km.rule_warnings == []
    assert topics(km, "always (Altitude[uav2] > 10)") == [("platform1", "topic2")]
    assert topics(km, "always (Close[uav1, uav2])") == [
        ("platform1", "topic6"),
        ("platform1", "topic8"),
    ]
    assert topics(km, "always (Position[car1] > 0)") == [("platform2", "carstopic3")]


def test_b_explains_the_remote_topic_a_local_one_displaced(scenario: Path) -> None:
    """`explain --topic uastopic7` of this policy ended in an IndexError."""
    km = KnowledgeManager.from_config(policy(scenario, PREFER_LOCAL))
    text = all_explained(km, "for all x in UAV □(Close[uav1, x])", topic="uastopic7")
    e = km.explain("for all x in UAV □(Close[uav1, x])", topic="uastopic7")
    reasons = {f.feature: [n.reason for n in f.why_not] for f in e.features}
    assert reasons["Close[uav1, uav2]"] == [
        "veto(1, platform3, uastopic7) holds [own.dl:1]; Close[uav1, uav2] maps to "
        "Near[uas20, uas21] on platform3"
    ]
    assert "✘ uastopic7 on platform3: veto(1, platform3, uastopic7) holds" in text


# ---- c. Height (platform3) ≡ Altitude (platform1) without the COWL file's bridge ------------


def without_the_altitude_bridge(scenario: Path) -> None:
    drop_rule(scenario / "mappings" / "platform1-platform3.cowl.xml", P1 + "Altitude")


def test_c_a_bridge_told_as_a_fact_in_a_rule_file(scenario: Path) -> None:
    without_the_altitude_bridge(scenario)
    plain = KnowledgeManager.from_config(scenario / "federation.toml")
    assert topics(plain, "Altitude[uav2] > 1") == [("platform1", "topic2")]
    km = KnowledgeManager.from_config(
        policy(scenario, "bridge('platform1', 'Altitude', 'platform3', 'Height', 'equiv')\n")
    )
    assert topics(km, "Altitude[uav2] > 1") == [("platform1", "topic2"), ("platform3", "uastopic5")]
    (why,) = km.explain("Altitude[uav2] > 1", topic="uastopic5").features[0].why
    assert why.summary[0] == (
        "feature: Altitude ≡ Height (bridge platform1→platform3, own.dl:1) ≡ Alt (platform3 "
        f"axiom, {scenario / 'ontologies' / 'platform3.owl'})"
    )


def test_c_a_bridge_by_a_rule_of_ones_own_is_in_the_summary(scenario: Path) -> None:
    """The summary omitted a link a rule file derived."""
    without_the_altitude_bridge(scenario)
    km = KnowledgeManager.from_config(
        policy(
            scenario,
            "eq_step(R, 'platform1', 'Altitude', R, 'Height') <= context('platform1', R) "
            "& (R == 'platform3')\n",
        )
    )
    assert topics(km, "Altitude[uav2] > 1") == [("platform1", "topic2"), ("platform3", "uastopic5")]
    (why,) = km.explain("Altitude[uav2] > 1", topic="uastopic5").features[0].why
    assert (
        "rule: eq_step(platform3, platform1, Altitude, platform3, Height) [own.dl:1]" in why.summary
    )


def test_c_a_rule_deriving_an_input_is_refused_with_its_place(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Deriving into bridge/5 made explain crash."""
    config = policy(
        scenario,
        "bridge('platform1', 'Altitude', R, 'Height', 'equiv') <= platform(R) "
        "& (R == 'platform3')\n",
    )
    code = main(["explain", "--config", str(config), "Altitude[uav2] > 1"])
    out = capsys.readouterr()
    assert code == 2
    assert out.err.startswith(
        "error: own.dl:1:1: bridge is an input relation (declared at rules/schema.dl:"
    )
    assert out.err.endswith("rules may not derive it, though facts may tell it\n")


# ---- d. ids from a data property hasId -----------------------------------------------------

HAS_ID = """@prefix : <http://d.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:hasId a owl:DatatypeProperty .
:follows a owl:ObjectProperty .
:UnaryRelation a owl:Class .
:UAV a owl:Class .
:Speed rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :UnaryRelation
    [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :UAV ] ) ] .
:alpha a owl:NamedIndividual, :UAV ; :hasId 7 ; :follows :uav1 .
:uav1 a owl:NamedIndividual, :UAV ; :hasId 42 .
"""


def test_d_ids_from_a_data_property_are_one_rule(tmp_path: Path) -> None:
    (tmp_path / "d.ttl").write_text(HAS_ID)
    (tmp_path / "d.sslt").write_text(
        "topic speeds:M contains Speed(UAV) = msg.v for some UAV = msg.id\n"
    )
    (tmp_path / "own.dl").write_text("told_id(P, O, V) <= data_property(P, O, 'hasId', V)\n")
    table = '[platforms.d]\nontology = "d.ttl"\nspecs = "d.sslt"\n'
    (tmp_path / "plain.toml").write_text(table)
    (tmp_path / "d.toml").write_text('rules = ["own.dl"]\n' + table)
    plain = KnowledgeManager.from_config(tmp_path / "plain.toml")
    assert plain.query("data_property(_P, O, 'hasId', V)").rows == (
        ("http://d.org/o#alpha", 7),
        ("http://d.org/o#uav1", 42),
    )
    assert plain.query("object_property(_P, O, 'follows', Other)").rows == (
        ("http://d.org/o#alpha", "http://d.org/o#uav1"),
    )
    with pytest.raises(MissingIdError, match="object alpha on d has no id"):
        plain.check_formula("Speed[alpha] > 1")
    km = KnowledgeManager.from_config(tmp_path / "d.toml")
    for obj, id_ in (("alpha", 7), ("uav1", 42)):  # hasId, not the digits ending uav1
        (feature,) = km.check_formula(f"Speed[{obj}] > 1").features
        assert [t.filter for t in feature.topics] == [(("msg.id", id_),)]
    (why,) = km.explain("Speed[alpha] > 1").features[0].why
    assert "rule: told_id(d, alpha, 7) [own.dl:1]" in why.summary


# ---- e. a topic naming the object before one reading `every UAV` ---------------------------

EVERY_LAST = (
    "rank(Q, P, T, 1) <= matched_topic(Q, P, T, K, _C1, _C2, _C3) "
    "& topic_arg(P, T, K, _I, 'every', _S, _Id)\n"
)


def every_topic_first(scenario: Path) -> None:
    specs = scenario / "specs" / "platform1.sslt"
    specs.write_text(
        "topic topic0:UavMsg contains Altitude(UAV) = msg.alt for every UAV = msg.id\n"
        + specs.read_text()
    )


def test_e_ranking_a_topic_below_another_is_one_rank(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    every_topic_first(scenario)
    plain = KnowledgeManager.from_config(scenario / "single.toml")
    assert topics(plain, "Altitude[uav1] > 1") == [
        ("platform1", "topic0"),
        ("platform1", "topic1"),
        ("platform1", "topic2"),
    ]
    km = KnowledgeManager.from_config(policy(scenario, EVERY_LAST, "single.toml"))
    assert topics(km, "Altitude[uav1] > 1") == [
        ("platform1", "topic1"),  # ties keep the order the specs are written in
        ("platform1", "topic2"),
        ("platform1", "topic0"),
    ]
    why = {w.topic: w.summary for w in km.explain("Altitude[uav1] > 1").features[0].why}
    assert "rank 1: rank(0, platform1, topic0, 1) [own.dl:1]" in why["topic0"]
    assert not any(line.startswith(("rank", "age")) for line in why["topic1"])
    out = golden(
        capsys,
        scenario / "golden",
        scenario / "own-single.toml",
        {
            "query": "relevant_topic('Altitude', ('uav1',), T, Filter)",
            "expect": [
                {"T": "topic0", "Filter": [1]},
                {"T": "topic1", "Filter": [1]},
                {"T": "topic2", "Filter": [1]},
            ],
        },
    )
    assert out.splitlines()[-1] == "1 passed, 0 failed"


def test_e_a_dropped_topic_is_explained(scenario: Path) -> None:
    """The fallback: the `every` topic only when no topic names the object.  Explaining the
    topic it drops ended in a crash."""
    every_topic_first(scenario)
    km = KnowledgeManager.from_config(
        policy(
            scenario,
            ".decl named(Query, Platform)\n"
            "named(Q, P) <= matched_topic(Q, P, T, K, _C1, _C2, _C3) "
            "& topic_arg(P, T, K, 1, 'object', _O, _Id)\n"
            "veto(Q, P, T) <= matched_topic(Q, P, T, K, _C1, _C2, _C3) "
            "& topic_arg(P, T, K, _I, 'every', _S, _Id) & named(Q, P)\n",
            "single.toml",
        )
    )
    assert km.rule_warnings == []
    assert topics(km, "Altitude[uav1] > 1") == [("platform1", "topic1"), ("platform1", "topic2")]
    assert topics(km, "Altitude[uav2] > 1") == [("platform1", "topic0"), ("platform1", "topic2")]
    text = all_explained(km, "Altitude[uav1] > 1", topic="topic0")
    assert "✘ topic0 on platform1: veto(0, platform1, topic0) holds [own.dl:3]" in text
