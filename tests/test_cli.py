"""The CLI: thesis-style text, exact JSON, spec management, and one-line errors (exit 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from dkreason.cli import main

from .conftest import SCENARIOS, entity_bomb


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out + out.err


def test_match_text_follows_the_thesis_listings(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = run(
        capsys, "match", "--config", str(SCENARIOS / "federation.toml"), "Altitude[uav2] > 1"
    )
    assert code == 0
    assert out.splitlines() == [
        "Feature: Altitude[uav2]",
        "Topics to merge:",
        "  Topic: topic2, Message type: UavMsg, Id: msg.id = 2, Field: msg.alt",
        "  Topic: uastopic5 (platform platform3, as Alt[uas21]), Message type: UasMsg, "
        "Id: msg.id = 21, Field: msg.alt",
    ]


def test_specs_add_show_list_remove_and_sort(
    capsys: pytest.CaptureFixture[str], scenario: Path
) -> None:
    config = str(scenario / "federation.toml")
    new = "topic topic10:UavMsg contains Altitude(uav2) = msg.alt for uav2 = msg.id"
    assert run(capsys, "specs", "add", "--config", config, new) == (
        0,
        "added topic10 to platform1\n",
    )
    assert run(capsys, "specs", "show", "--config", config, "topic10") == (0, new + "\n")
    code, out = run(capsys, "specs", "list", "--config", config)
    assert code == 0 and f"platform1: {new}" in out.splitlines()
    assert sum(line.startswith("platform3: ") for line in out.splitlines()) == 8
    assert run(capsys, "specs", "remove", "--config", config, "topic10")[0] == 0
    assert run(capsys, "sort", "--config", config, "UAV") == (0, "uav1\nuav2\n")


BAD_SSLT = "topic t1:M contains Speed(uav1 = msg.spd\n"
MISFIT_SSLT = "topic t1:M contains Altitude(car1) = msg.alt for car1 = msg.id\n"
BOMB = entity_bomb("Topic_specs")
EXTERNAL = (
    '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
    "<Topic_specs>&x;</Topic_specs>\n"
)
BIRD = (
    '<NamedIndividual rdf:about="&ont;bird"><rdf:type rdf:resource="&ontology;UAV"/>'
    "</NamedIndividual>\n</rdf:RDF>"
)
TWIN = (
    '<NamedIndividual rdf:about="http://other.org/x#uav1"><rdf:type '
    'rdf:resource="&ontology;UAV"/></NamedIndividual>\n</rdf:RDF>'
)


def _variant(
    scenario: Path,
    *,
    specs: str | None = None,
    specs_name: str = "s.sslt",
    ontology_edit: tuple[str, str] | None = None,
    config_text: str | None = None,
) -> str:
    config = scenario / "variant.toml"
    text = (scenario / "single.toml").read_text()
    if specs is not None:
        (scenario / specs_name).write_text(specs)
        text = text.replace("specs/platform1.sslt", specs_name)
    if ontology_edit is not None:
        owl = (scenario / "ontologies" / "platform1.owl").read_text()
        (scenario / "o.owl").write_text(owl.replace(*ontology_edit))
        text = text.replace("ontologies/platform1.owl", "o.owl")
    config.write_text(config_text if config_text is not None else text)
    return str(config)


ERRORS: dict[str, tuple[dict[str, Any], str, str]] = {
    "unknown feature": ({}, "always (Altitud[uav1] > 3)", "unknown feature 'Altitud'"),
    "unknown object": ({}, "Altitude[uav9] > 3", "unknown object 'uav9'"),
    "wrong arity": ({}, "Close[uav1]", "Close takes 2 arguments, not 1"),
    "wrong sort": ({}, "Altitude[car1] > 3", "car1 is a Car, Altitude needs AerialVehicle"),
    "unknown quantifier sort": ({}, "forall x in Trucks: Speed[x] > 3", "unknown sort 'Trucks'"),
    "variable sort not subsumed": (
        {},
        "forall x in Vehicle: GroundSpeed[x] > 3",
        "which is not subsumed by UAV",
    ),
    "formula syntax": ({}, "always (Altitude[uav1] > )", "<formula>:1:26: syntax error"),
    "SSL_T syntax": ({"specs": BAD_SSLT}, "Speed[uav1]", "s.sslt:1:32: syntax error"),
    "SSL_T misfit": (
        {"specs": MISFIT_SSLT},
        "Speed[uav1]",
        "s.sslt:1:30: topic t1: argument 1 of Altitude does not fit",
    ),
    "malformed XML": (
        {"specs": "<Topic_specs><Topic>", "specs_name": "s.xml"},
        "Speed[uav1]",
        "s.xml:1:21: malformed XML",
    ),
    "malformed RDF": ({"ontology_edit": ("</rdf:RDF>", "")}, "Speed[uav1]", "malformed XML"),
    "missing file": (
        {
            "ontology_edit": ("", ""),
            "config_text": 'local = "p"\n[platforms.p]\nontology = "nope.owl"\n',
        },
        "Speed[uav1]",
        "nope.owl: no such file",
    ),
    "TOML syntax": (
        {"config_text": 'local = "platform1\n'},
        "Speed[uav1]",
        "variant.toml:1:19: TOML syntax error",
    ),
    "ambiguous name": (
        {"ontology_edit": ("</rdf:RDF>", TWIN)},
        "Altitude[uav1] > 3",
        "ambiguous object 'uav1' on platform1: <http://other.org/x#uav1> and",
    ),
    "missing id": (
        {"ontology_edit": ("</rdf:RDF>", BIRD)},
        "Altitude[bird] > 3",
        "object bird on platform1 has no id",
    ),
    "external entity": (
        {"specs": EXTERNAL, "specs_name": "s.xml"},
        "Speed[uav1]",
        "external entity 'x' (file:///etc/passwd) refused",
    ),
    "entity bomb": ({"specs": BOMB, "specs_name": "s.xml"}, "Speed[uav1]", "amplification factor"),
}


@pytest.mark.parametrize("case", list(ERRORS))
def test_bad_input_prints_exactly_one_line_and_exits_2(
    capsys: pytest.CaptureFixture[str], scenario: Path, case: str
) -> None:
    variant, formula, says = ERRORS[case]
    config = _variant(scenario, **variant)
    code, out = run(capsys, "match", "--config", config, formula)
    assert code == 2
    assert out.count("\n") == 1 and out.startswith("error: ") and says in out, out


def test_usage_errors_are_one_line_too() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "dkreason.cli", "match"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 2
    assert (proc.stdout + proc.stderr).count("\n") == 1


@pytest.mark.parametrize(
    ("rule", "says", "line"),
    [
        ("relevant(X) <= wanted(X, _A, _B, _C, _D) &", "not a rule", 2),
        ("relevant(X) <= wanted(X, _, _, _, _)", "bare `_`", 2),
        ("relevant(X) <= wanted(X + 1, _A, _B, _C, _D)", "unsupported term 'X + 1'", 2),
        ("relevant(X)", "X is a variable, and a fact holds constants only", 2),
        ("relevant", "expected a rule `head(...) <= body` or a fact", 2),
        (".decl relevant(X) materialized\nrelevant(X) <= local(X)", "expected `.decl name", 2),
        (".decl relevant(X)\n.decl relevant(Y)", "relevant is declared twice (first at", 3),
        # a misspelt relation, a wrong arity, an undeclared one, a query no rule derives
        (
            ".decl near(L, R)\nnear(L, R) <= contxt(L, R)",
            "undeclared relation contxt/2 (did you mean context/2?)",
            3,
        ),
        (
            "feature_candidate(R, F) <= local(R) & feature(R, F, _N)",
            "feature_candidate has 3 columns (Platform, LocalFeature, Feature, declared at",
            2,
        ),
        ("zzz(X) <= local(X)", "undeclared relation zzz/1 (declare it with `.decl`)", 2),
    ],
)
def test_a_bad_rule_file_is_one_line_naming_file_and_line(
    capsys: pytest.CaptureFixture[str], scenario: Path, rule: str, says: str, line: int
) -> None:
    (scenario / "mine.dl").write_text(f"# my policy\n{rule}\n")
    config = scenario / "single.toml"
    config.write_text('rules = ["mine.dl"]\n' + config.read_text())
    code, out = run(capsys, "match", "--config", str(config), "Altitude[uav1] > 1")
    assert code == 2 and len(out.splitlines()) == 1
    assert f"mine.dl:{line}" in out and says in out, out
