"""End to end: the thesis case studies reproduce their listings (expected/*.json)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dkreason import KnowledgeManager

from .conftest import SCENARIOS, formulas, topic_sets

CASES = sorted((SCENARIOS / "expected").glob("*.json"))
_managers: dict[str, KnowledgeManager] = {}


def manager(config: str) -> KnowledgeManager:
    if config not in _managers:
        _managers[config] = KnowledgeManager.from_config(SCENARIOS / config)
    return _managers[config]


def twin(formula: str) -> str:
    table = formulas()
    key = next(k for k, v in table.items() if v == formula and not k.endswith("-ascii"))
    return table[f"{key}-ascii"]


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.stem)
@pytest.mark.parametrize("spelling", ["thesis", "ascii"])
@pytest.mark.parametrize("form", ["sslt", "xml"])
def test_thesis_case_matches_listing(case: Path, spelling: str, form: str) -> None:
    want = json.loads(case.read_text(encoding="utf-8"))
    config = want["config"] if form == "sslt" else want["config"].replace(".toml", "-xml.toml")
    formula = want["formula"] if spelling == "thesis" else twin(want["formula"])
    got = manager(config).check_formula(formula).to_json()
    assert topic_sets(got) == topic_sets(want)
    assert len(got["features"]) == len(want["features"])


def test_remote_topics_say_what_they_were_matched_as() -> None:
    got = manager("federation.toml").check_formula("Altitude[uav2] > 3").to_json()
    (remote,) = [t for t in got["features"][0]["topics"] if t["platform"] != "platform1"]
    assert remote["as"] == {"feature": "Alt", "args": ["uas21"]}


# ---- any mix of object and sort arguments matches as the definition says ---------------------

MIXED_ONTOLOGY = (
    """@prefix : <http://mix.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:A a owl:Class .
:B a owl:Class ; rdfs:subClassOf :A .
:UnaryRelation a owl:Class .
:BinaryRelation a owl:Class .
:TernaryRelation a owl:Class .
"""
    + "".join(
        f":{f} rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( :{kind} "
        + " ".join(
            f"[ a owl:Restriction ; owl:onProperty :arg{i} ; owl:allValuesFrom :A ]"
            for i in range(1, n + 1)
        )
        + " ) ] .\n"
        for f, kind, n in (
            ("U", "UnaryRelation", 1),
            ("P", "BinaryRelation", 2),
            ("T", "TernaryRelation", 3),
        )
    )
    + """
:a1 a owl:NamedIndividual, :A .
:b2 a owl:NamedIndividual, :B .
:b3 a owl:NamedIndividual, :B .
"""
)
SORTS = {"A": {"a1", "b2", "b3"}, "B": {"b2", "b3"}}
ARITY = {"U": 1, "P": 2, "T": 3}
ENTITIES = ["a1", "b2", "b3", "A", "B"]


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(sorted(ARITY)),
            st.lists(st.sampled_from(ENTITIES), min_size=3, max_size=3),
        ),
        min_size=1,
        max_size=8,
    ),
    st.lists(
        st.tuples(
            st.sampled_from(sorted(ARITY)),
            st.lists(st.sampled_from(["a1", "b2", "b3"]), min_size=3, max_size=3),
        ),
        min_size=1,
        max_size=4,
    ),
)
def test_topics_with_any_mix_of_object_and_sort_arguments_match_by_definition(
    tmp_path: Path, specs: list[tuple[str, list[str]]], wanted: list[tuple[str, list[str]]]
) -> None:
    """A topic serves F[o1, …] when it carries F and each of its arguments names o_i or a sort
    o_i belongs to, whichever positions are sorts (the matcher keys a topic by its first sort
    argument and checks the rest), with each argument's filter the object's id."""
    lines = []
    for n, (f, args) in enumerate(specs):
        named = [f"{e} as x{i}" for i, e in enumerate(args[: ARITY[f]], 1)]
        fields = [
            f"{'some ' if e in SORTS else ''}x{i} = msg.id{i}"
            for i, e in enumerate(args[: ARITY[f]], 1)
        ]
        lines.append(
            f"topic t{n}:M contains {f}({', '.join(named)}) = msg.v for {', '.join(fields)}"
        )
    (tmp_path / "mix.ttl").write_text(MIXED_ONTOLOGY, encoding="utf-8")
    (tmp_path / "mix.sslt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    (tmp_path / "mix.toml").write_text(
        '[platforms.mix]\nontology = "mix.ttl"\nspecs = "mix.sslt"\n', encoding="utf-8"
    )
    km = KnowledgeManager.from_config(tmp_path / "mix.toml")
    features = {(f, tuple(objects[: ARITY[f]])) for f, objects in wanted}
    text = " and ".join(f"{f}[{', '.join(objects)}] > 0" for f, objects in sorted(features))
    request = km.check_formula(text)
    got = {
        (f.feature.key.name, f.feature.key.args): sorted(
            (t.topic, tuple(sorted(t.filter))) for t in f.topics
        )
        for f in request.features
    }

    def serves(entity: str, obj: str) -> bool:
        return obj in SORTS[entity] if entity in SORTS else entity == obj

    expected = {
        (f, objects): sorted(
            (f"t{n}", tuple(sorted((f"msg.id{i}", int(o[1:])) for i, o in enumerate(objects, 1))))
            for n, (g, args) in enumerate(specs)
            if g == f and all(serves(e, o) for e, o in zip(args, objects, strict=False))
        )
        for f, objects in features
    }
    assert got == expected
