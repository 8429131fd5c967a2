"""Hostile and careless input, one regression test per defect of issue 12: every bad input is
one line and exit 2 (or a result), never a traceback, a hang or unbounded memory."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import ParseError, WireError
from dkreason.live import wire
from dkreason.parse.formula import parse_formula
from dkreason.parse.owl import parse_ontology
from dkreason.progress import Progressor

from .conftest import entity_bomb

REPO = Path(__file__).resolve().parents[1]
SINGLE = REPO / "examples" / "single.toml"


def one_line_error(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run the CLI in-process; it must exit 2 with exactly one line on stderr."""
    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith(("error: ", "dkreason")), err
    return err


def rows(path: Path, lines: Sequence[str | bytes]) -> Path:
    path.write_bytes(b"".join((x if isinstance(x, bytes) else x.encode()) + b"\n" for x in lines))
    return path


# ---- 5. live payloads ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "payload",
    [
        b"[" * 30000,
        b'{"valid": 1, "msg": {"x": ' + b"9" * 5000 + b"}}",
        bytes([0x80, 0x81]),
        b'{"valid": 1, "msg": ' + b'{"a":' * 5000 + b"1" + b"}" * 5001,
    ],
)
def test_a_bad_payload_is_a_wire_error(payload: bytes) -> None:
    with pytest.raises(WireError):
        wire.topic_message(payload, "platform2/topic3")
    with pytest.raises(WireError):
        wire.decode(payload, wire.MAX_KNOWLEDGE, "platform2's objects")


def test_a_string_sample_value_is_an_error_and_nan_is_unknown(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = rows(
        tmp_path / "r.jsonl",
        [json.dumps({"topic": "topic3", "time": t, "msg": {"id": 1, "spd": 50}}) for t in range(3)]
        + [
            '{"topic": "topic3", "time": 3, "msg": {"id": 1, "spd": NaN}}',
            '{"topic": "topic3", "time": 4, "msg": {"id": 1, "spd": "far"}}',
        ],
    )
    code = main(
        [
            "monitor",
            "--config",
            str(SINGLE),
            "--source",
            str(source),
            "--json",
            "always (Speed[car1] >= 0)",
        ]
    )
    out = capsys.readouterr()
    assert code == 2 and "str 'far' is not a number or boolean" in out.err
    assert out.err.count("\n") == 1 and '"verdict": false' not in out.out


def test_nan_in_a_sample_is_unknown_not_a_violation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = rows(
        tmp_path / "r.jsonl",
        [json.dumps({"topic": "topic3", "time": t, "msg": {"id": 1, "spd": 50}}) for t in range(3)]
        + [
            '{"topic": "topic3", "time": 3, "msg": {"id": 1, "spd": NaN}}',
            '{"topic": "topic3", "time": 4, "msg": {"id": 1, "spd": Infinity}}',
        ],
    )
    code = main(
        [
            "monitor",
            "--config",
            str(SINGLE),
            "--source",
            str(source),
            "--json",
            "always (Speed[car1] >= 0)",
        ]
    )
    verdicts = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert code == 3 and verdicts[-1]["verdict"] is None


def test_an_unhashable_id_matches_no_object(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = rows(
        tmp_path / "r.jsonl",
        [
            '{"topic": "topic3", "time": 0, "msg": {"id": [1], "spd": 50}}',
            '{"topic": "topic3", "time": 1, "msg": {"id": 1, "spd": 50}}',
        ],
    )
    assert (
        main(
            [
                "monitor",
                "--config",
                str(SINGLE),
                "--source",
                str(source),
                "--json",
                "always (Speed[car1] >= 0)",
            ]
        )
        == 0
    )


# ---- 6. the compiled progressor takes formulas of any size ---------------------------------


def test_hundreds_of_conjuncts_under_a_temporal_operator() -> None:
    formula = "always (" + " and ".join(f"X[a{i}] > {i}" for i in range(400)) + ")"
    progressor = Progressor()
    progressor.add(formula)
    assert progressor.step(0, {f"X[a{i}]": i + 1 for i in range(400)}) == []
    (verdict,) = progressor.step(1, {f"X[a{i}]": i for i in range(400)})
    assert verdict.verdict is False


def test_a_forall_over_hundreds_of_objects_compiles(tmp_path: Path) -> None:
    cars = "".join(f":car{i} a owl:NamedIndividual, :Car .\n" for i in range(303))
    (tmp_path / "o.ttl").write_text(
        "@prefix : <http://road.org/o#> .\n@prefix owl: <http://www.w3.org/2002/07/owl#> .\n"
        "@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .\n"
        ":Car a owl:Class .\n:UnaryRelation a owl:Class .\n"
        ":Speed a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf ( "
        ":UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Car ] "
        ") ] .\n" + cars
    )
    (tmp_path / "c.toml").write_text('[platforms.road]\nontology = "o.ttl"\n')
    plan = KnowledgeManager.from_config(tmp_path / "c.toml").plan(
        "forall c in Car: always (Speed[c] > 0)"
    )
    progressor = Progressor()
    for f in plan.formulas:
        progressor.add(f.text, f.tree)
    (verdict,) = progressor.step(0, dict.fromkeys(plan.formulas[0].keys, -1))
    assert verdict.verdict is False


def test_an_infinite_literal_compiles() -> None:
    progressor = Progressor()
    progressor.add("always (X[a] < 1e309)")
    assert progressor.step(0, {"X[a]": 5.0}) == []
    (verdict,) = progressor.finish()
    assert verdict.verdict is True


# ---- 7. formula parser ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "formula",
    [
        "not " * 1000 + "P[a]",
        "(not " * 1000 + "P[a]" + ")" * 1000,
        "always " * 600 + "P[a]",
        "X[a] > " + "9" * 4400,
        "always[٣,٤] P[a]",
        "always[0, " + "1" * 5000 + "] P[a]",
        "P[a] -> " * 1000 + "P[a]",
    ],
)
def test_formulas_past_the_limits_are_parse_errors(formula: str) -> None:
    with pytest.raises(ParseError):
        parse_formula(formula)


def test_a_long_flat_conjunction_and_redundant_parentheses_are_not_too_deep() -> None:
    parse_formula(" and ".join(f"P[a{i}]" for i in range(5000)))
    parse_formula("(" * 1000 + "X[a] > 1" + ")" * 1000)


def test_deep_formula_on_the_cli_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    one_line_error(capsys, "match", "--config", str(SINGLE), "not " * 1000 + "P[a]")
    one_line_error(
        capsys,
        "progress",
        "--states",
        str(REPO / "tests/data/thesis-states.jsonl"),
        "not " * 1000 + "P[a]",
    )


# ---- 8. JSONL recordings and state files ---------------------------------------------------

BAD_LINES = {
    "non-UTF-8": bytes([0x7B, 0xFF, 0x7D]),
    "deep": "[" * 100_000,
    "long number": '{"topic": "topic3", "time": ' + "9" * 5000 + ', "msg": {}}',
    "topic list": '{"topic": ["topic3"], "time": 1, "msg": {"id": 1, "spd": 2}}',
    "huge time": '{"topic": "topic3", "time": 1e999999999, "msg": {"id": 1, "spd": 2}}',
    "tiny time": '{"topic": "topic3", "time": 1e-999999999, "msg": {"id": 1, "spd": 2}}',
    "nan time": '{"topic": "topic3", "time": NaN, "msg": {"id": 1, "spd": 2}}',
    "deep msg": '{"topic": "topic3", "time": 1, "msg": ' + '{"a":' * 900 + "1" + "}" * 901,
}


@pytest.mark.parametrize("bad", BAD_LINES.values(), ids=BAD_LINES.keys())
def test_a_bad_recording_line_keeps_the_lines_before_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: str | bytes
) -> None:
    good = [
        json.dumps({"topic": "topic3", "time": t, "msg": {"id": 1, "spd": 70 if t < 3 else 10}})
        for t in range(6)
    ]
    source = rows(tmp_path / "r.jsonl", [*good, bad, good[0]])
    code = main(
        [
            "monitor",
            "--config",
            str(SINGLE),
            "--source",
            str(source),
            "--json",
            "always (Speed[car1] > 50)",
        ]
    )
    out = capsys.readouterr()
    assert code == 2 and out.err.count("\n") == 1 and "r.jsonl:7" in out.err
    assert '"verdict": false' in out.out  # decided on the lines before the damage


STATE_LINES = {
    "non-UTF-8": bytes([0x7B, 0xFF, 0x7D]),
    "deep": "[" * 100_000,
    "long number": '{"time": 1, "values": {"P[a]": ' + "9" * 5000 + "}}",
    "string value": '{"time": 1, "values": {"P[a]": "yes"}}',
    "object value": '{"time": 1, "values": {"P[a]": {"x": 1}}}',
    "huge time": '{"time": 1e999999999, "values": {}}',
    "string time": '{"time": "1e999999999", "values": {}}',
}


@pytest.mark.parametrize("bad", STATE_LINES.values(), ids=STATE_LINES.keys())
def test_a_bad_state_line_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: str | bytes
) -> None:
    states = rows(tmp_path / "s.jsonl", ['{"time": 0, "values": {"P[a]": true}}', bad])
    err = one_line_error(capsys, "progress", "--states", str(states), "always P[a]")
    assert "s.jsonl:2" in err


def test_nan_in_a_state_is_unknown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    states = rows(
        tmp_path / "s.jsonl",
        ['{"time": 0, "values": {"X[a]": 1}}', '{"time": 1, "values": {"X[a]": NaN}}'],
    )
    assert main(["progress", "--states", str(states), "always (X[a] > 0)"]) == 3


# ---- 9. config, ontology and command-line values -------------------------------------------


def config_with(tmp_path: Path, body: str) -> Path:
    shutil.copy(REPO / "ontologies" / "platform1.owl", tmp_path / "p1.owl")
    path = tmp_path / "c.toml"
    path.write_text(body)
    return path


@pytest.mark.parametrize(
    "body",
    [
        'local = "p"\n[platforms.p]\nontology = "p1\\u0000.owl"\n',
        "rules = " + "[" * 5000 + "]" * 5000 + '\n[platforms.p]\nontology = "p1.owl"\n',
        'mappings = 5\n[platforms.p]\nontology = "p1.owl"\n',
        'local = "p"\n[platforms.p]\nontology = "p1\\n.owl"\n',
    ],
)
def test_bad_configs_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str
) -> None:
    one_line_error(capsys, "match", "--config", str(config_with(tmp_path, body)), "P[a]")


TTL = """@prefix : <http://ex.org/o#> . @prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
:Car a owl:Class . {extra}
"""


@pytest.mark.parametrize(
    "extra",
    [
        ":car" + "1" * 5000 + " a :Car .",
        ':car1 a :Car ; :id "abc"^^xsd:integer .',
    ],
)
def test_odd_individuals(tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str) -> None:
    (tmp_path / "o.ttl").write_text(TTL.replace("{extra}", extra))
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.ttl"\n')
    code = main(["match", "--config", str(tmp_path / "c.toml"), "forall c in Car: true"])
    err = capsys.readouterr().err
    assert code in (0, 2) and err.count("\n") <= 1 and "Traceback" not in err
    if "abc" in extra:
        assert code == 2 and "not a valid integer" in err


@pytest.mark.parametrize(
    "argv",
    [
        ["serve", "--config", str(SINGLE), "--speed", "inf"],
        ["serve", "--config", str(SINGLE), "--speed", "nan"],
        ["serve", "--config", str(SINGLE), "--origin", "nan"],
        ["serve", "--config", str(SINGLE), "--heartbeat", "nan"],
        ["monitor", "--config", str(SINGLE), "--live", "--wait", "nan", "P[a]"],
        # numbers past what a clock or a timer holds (issue 27, defect 6): refused as given
        ["serve", "--config", str(SINGLE), "--heartbeat", "1e300"],
        ["monitor", "--config", str(SINGLE), "--live", "--wait", "1e300", "P[a]"],
        ["monitor", "--config", str(SINGLE), "--live", "--duration", "1e300", "P[a]"],
        ["batch", "--config", str(SINGLE), "--timeout", "1e300", "x.jsonl"],
        [
            "monitor",
            "--config",
            str(SINGLE),
            "--source",
            "x.jsonl",
            "--max-age",
            "1e999999999",
            "P[a]",
        ],
    ],
)
def test_bad_numbers_on_the_command_line(
    capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.count("\n") == 1


@pytest.mark.parametrize(
    "option", [("--origin", "1e300"), ("--origin", "-1e300"), ("--speed", "1e300")]
)
def test_a_replay_clock_past_what_a_clock_holds_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: tuple[str, str]
) -> None:
    """Issue 27, defect 6: `serve --origin 1e300` overflowed the replay's clock (a
    traceback, exit 1, which reads as "violated")."""
    recording = rows(tmp_path / "r.jsonl", ['{"topic": "topic1", "time": 1, "msg": {"id": 1}}'])
    with pytest.raises(SystemExit) as stop:
        main(["serve", "--config", str(SINGLE), "--source", str(recording), *option])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.count("\n") == 1 and option[0] in err


def test_plot_into_a_missing_directory_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = rows(
        tmp_path / "r.jsonl", ['{"topic": "topic3", "time": 0, "msg": {"id": 1, "spd": 1}}']
    )
    one_line_error(
        capsys,
        "monitor",
        "--config",
        str(SINGLE),
        "--source",
        str(source),
        "--plot",
        str(tmp_path / "no" / "x.png"),
        "Speed[car1] > 0",
    )


def test_a_malformed_zenoh_config_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "z.json5").write_text('{ mode: "peer", bad bad\n')
    err = one_line_error(
        capsys,
        "monitor",
        "--live",
        "--config",
        str(SINGLE),
        "--zenoh-config",
        str(tmp_path / "z.json5"),
        "P[a]",
    )
    assert "z.json5:1:" in err


# ---- 10. devices, FIFOs, huge files --------------------------------------------------------


@pytest.mark.parametrize("what", ["ontology", "specs", "mapping", "config", "states", "zenoh"])
def test_a_device_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], what: str
) -> None:
    zero = "/dev/zero"
    cfg = config_with(tmp_path, "")
    mapping = tmp_path / "m.toml"
    text = {
        "ontology": f'[platforms.p]\nontology = "{zero}"\n',
        "specs": f'[platforms.p]\nontology = "p1.owl"\nspecs = "{zero}.sslt"\n',
        "mapping": f'local = "p"\n[platforms.p]\nontology = "p1.owl"\n[platforms.q]\n'
        f'ontology = "p1.owl"\n[[mappings]]\nsource = "p"\ntarget = "q"\n'
        f'file = "{zero}"\n',
    }.get(what, '[platforms.p]\nontology = "p1.owl"\n')
    if what == "specs":
        os.symlink(zero, tmp_path / "zero.sslt")
        text = text.replace(f"{zero}.sslt", "zero.sslt")
    cfg.write_text(text)
    mapping.write_text("")
    if what == "config":
        err = one_line_error(capsys, "match", "--config", zero, "P[a]")
    elif what == "states":
        err = one_line_error(capsys, "progress", "--states", zero, "P[a]")
    elif what == "zenoh":
        err = one_line_error(
            capsys, "monitor", "--live", "--config", str(cfg), "--zenoh-config", zero, "P[a]"
        )
    else:
        err = one_line_error(capsys, "match", "--config", str(cfg), "P[a]")
    assert "not a regular file" in err


def test_a_fifo_is_refused_not_waited_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    os.mkfifo(tmp_path / "o.owl")
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.owl"\n')
    assert "not a regular file" in one_line_error(
        capsys, "match", "--config", str(tmp_path / "c.toml"), "P[a]"
    )


def test_a_huge_line_is_refused_in_bounded_memory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "sparse.jsonl"
    with path.open("wb") as out:
        out.truncate(64 * 1024 * 1024)  # sparse: 64 MiB of NUL bytes, no newline
    assert "line longer than" in one_line_error(
        capsys, "monitor", "--config", str(SINGLE), "--source", str(path), "Speed[car1] > 0"
    )


def test_a_file_over_the_input_limit_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DKREASON_MAX_INPUT", "1K")
    assert "larger than 1024 bytes" in one_line_error(
        capsys, "match", "--config", str(SINGLE), "Speed[car1] > 0"
    )


# ---- 11. no external fetch in any RDF syntax -----------------------------------------------


@pytest.mark.parametrize(
    "context",
    [
        "http://127.0.0.1:9/ctx.jsonld",
        "file:///etc/passwd",
        ["x.jsonld", {"@vocab": "http://ex.org/"}],
    ],
)
def test_json_ld_names_no_context_to_fetch(context: list[Any] | str) -> None:
    doc = json.dumps({"@context": context, "@id": "http://ex.org/a", "@type": "Car"})
    with pytest.raises(ParseError, match="refused"):
        parse_ontology(doc.encode(), "o.jsonld", "p")


def test_json_ld_with_an_inline_context_is_read() -> None:
    doc = {
        "@context": {"@vocab": "http://ex.org/o#"},
        "@id": "http://ex.org/o#car1",
        "@type": "Car",
    }
    ontology = parse_ontology(json.dumps(doc).encode(), "o.jsonld", "p")
    assert "http://ex.org/o#car1" in ontology.individuals


def test_trix_goes_through_the_xml_hardening() -> None:
    with pytest.raises(ParseError, match="refused|malformed"):
        parse_ontology(entity_bomb("TriX").encode(), "o.trix", "p")
    external = (
        '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
        "<TriX>&x;</TriX>"
    )
    with pytest.raises(ParseError, match="refused"):
        parse_ontology(external.encode(), "o.trix", "p")


def test_a_peer_cannot_choose_the_parser() -> None:
    """The wire fixes Turtle: an RDF/XML reply named .owl is not read as XML."""
    xml = (REPO / "ontologies" / "platform1.owl").read_bytes()
    with pytest.raises(ParseError):
        parse_ontology(xml, "dkreason/p/ontology/p1.owl", "p", fmt="turtle")


# ---- 13. bounded expansion -----------------------------------------------------------------


def test_nested_quantifiers_past_the_bound_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    formula = "".join(f"forall x{i} in UAV: " for i in range(20)) + " and ".join(
        f"Altitude[x{i}] > 0" for i in range(20)
    )
    states = str(REPO / "tests/data/thesis-states.jsonl")
    err = one_line_error(capsys, "progress", "--config", str(SINGLE), "--states", states, formula)
    assert "more than the 100000" in err


def cyclic_ontology(n: int) -> str:
    """Sorts C0 ⊑ C1 ⊑ … ⊑ C0 and objects o0 = o1 = … = o0, one object typed in each sort."""
    head = (
        "@prefix : <http://www.example.com/ontology#> .\n"
        "@prefix owl: <http://www.w3.org/2002/07/owl#> .\n"
        "@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .\n"
        ":UnaryRelation a owl:Class .\n:Altitude a owl:Class ; rdfs:subClassOf [ a owl:Class ;"
        " owl:intersectionOf ( :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ;"
        " owl:allValuesFrom :C0 ] ) ] .\n"
    )
    return head + "".join(
        f":C{i} a owl:Class ; rdfs:subClassOf :C{(i + 1) % n} .\n"
        f":o{i} a owl:NamedIndividual, :C{i} ; owl:sameAs :o{(i + 1) % n} .\n"
        for i in range(n)
    )


def test_cyclic_subclass_and_same_as_chains_stay_linear(tmp_path: Path) -> None:
    """A 3000-step cycle makes 3000 equivalent sorts and 3000 sameAs objects: the knowledge
    base holds each class once (a representative), not its 9 million pairs."""
    n = 3000
    (tmp_path / "o.ttl").write_text(cyclic_ontology(n))
    (tmp_path / "s.sslt").write_text(
        "topic t1:M contains Altitude(C0) = msg.alt for some C0 = msg.id\n"
    )
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.ttl"\nspecs = "s.sslt"\n')
    km = KnowledgeManager.from_config(tmp_path / "c.toml")
    held = {view: len(rows) for view, rows in km.kb.engine.frozen().items()}
    assert sum(held.values()) < 10 * n, held
    request = km.check_formula("forall x in C1234: always (Altitude[x] > 1)")
    (feature,) = request.features  # one sameAs class: one object, named o0
    assert feature.feature.args == ("o0",)
    assert sorted(t.filter[0][1] for t in feature.topics) == list(range(n))  # each partner's id
    assert len(km.list_sort("C2999")) == n


def test_a_large_specs_file_costs_a_few_stored_rows_a_topic_and_one_check_a_use(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Defect 13: a 10 MB SSL_T file (86,000 topics) took 53 s and 2 GB.  A topic costs what it
    says and no more: its own facts (no padding rows), one keyed row per topic feature, and
    the signature check asks each distinct argument once, however many topics repeat it (the
    10 MB file now loads in about 26 s, 1.3 GB; from the cache, parsing is skipped)."""
    from dkreason.datalog import Datalog

    n = 5000
    shutil.copy(REPO / "ontologies" / "platform1.owl", tmp_path / "p1.owl")
    (tmp_path / "s.sslt").write_text(
        "".join(
            f"topic t{i}:UavMsg contains Altitude(uav1) = msg.alt for uav1 = msg.id, "
            f"Speed(UAV) = msg.spd for some UAV = msg.id\n"
            for i in range(n)
        )
    )
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "p1.owl"\nspecs = "s.sslt"\n')
    asked: list[int] = []
    ask = Datalog.ask

    def counted(self: Datalog, predicate: str, inputs: dict[str, Any], *args: Any) -> Any:
        if predicate == "spec_arg_fits":
            asked.append(len(inputs["spec_arg"]))
        return ask(self, predicate, inputs, *args)

    monkeypatch.setattr(Datalog, "ask", counted)
    km = KnowledgeManager.from_config(tmp_path / "c.toml")
    assert asked == [2]  # uav1 for Altitude, UAV for Speed
    sizes = {name: rows for name, (_, rows) in km.kb.engine.sizes().items()}
    per_topic = {
        "topic": 1,
        "topic_feature": 2,
        "topic_arg": 2,
        "topic_objects": 1,
        "sort_arg_at": 1,
    }
    for name, rows in per_topic.items():
        assert n * rows <= sizes[name] <= n * rows + 50, (name, sizes[name])
    request = km.check_formula("always (Speed[uav2] > 3)")
    assert len(request.features[0].topics) == n


def test_no_traceback_from_the_installed_command(tmp_path: Path) -> None:
    """The console script itself: one line on stderr, exit 2."""
    done = subprocess.run(
        [sys.executable, "-m", "dkreason.cli", "match", "--config", "/dev/zero", "P[a]"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1


# ---- 14. thousands of platform names outside the config ------------------------------------


def test_unknown_platforms_are_named_a_few_times_then_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from types import SimpleNamespace

    from dkreason.live.monitor import LiveMonitor

    monitor = SimpleNamespace(seen_strangers=set(), strangers=0)
    with caplog.at_level("WARNING", logger="dkreason.live"):
        for n in range(2000):
            LiveMonitor._stranger(monitor, f"fake{n}")  # type: ignore[arg-type]
    assert len(caplog.records) == 10 + 2  # ten named, then a count at 100 and 1000
    assert len(monitor.seen_strangers) == 10 and monitor.strangers == 2000


# ---- issue 27: the knowledge inputs --------------------------------------------------------


@pytest.mark.parametrize("where", ["ontology", "import"])
def test_a_symlink_loop_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str
) -> None:
    for f in (REPO / "tests" / "data" / "sosa-ssn").iterdir():
        shutil.copy(f, tmp_path / f.name)
    looped = tmp_path / ("weather.ttl" if where == "ontology" else "ssn.ttl")
    looped.unlink()
    os.symlink(tmp_path / "loop.ttl", looped)
    os.symlink(looped, tmp_path / "loop.ttl")
    (tmp_path / "c.toml").write_text('[platforms.w]\nontology = "weather.ttl"\n')
    err = one_line_error(capsys, "match", "--config", str(tmp_path / "c.toml"), "P[a]")
    assert looped.name in err and "symbolic links" in err


def test_a_deep_subclass_chain_is_one_line_not_a_quadratic_closure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each object of a 1,000-deep chain is a member of every sort above it: a million rows
    (1.27 GB) for a 60 KB file.  The closure is sized before it is made."""
    from dkreason.workloads import owl_rl_world

    (tmp_path / "o.ttl").write_text(owl_rl_world("subclass", 1000))
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.ttl"\n')
    err = one_line_error(capsys, "match", "--config", str(tmp_path / "c.toml"), "Battery[o1] > 1")
    assert "o.ttl" in err and "rows" in err


def test_a_chain_as_deep_as_real_hierarchies_go_is_read(tmp_path: Path) -> None:
    from dkreason.workloads import owl_rl_world

    (tmp_path / "o.ttl").write_text(owl_rl_world("subclass", 60))
    (tmp_path / "c.toml").write_text('[platforms.p]\nontology = "o.ttl"\n')
    assert len(KnowledgeManager.from_config(tmp_path / "c.toml").list_sort("Robot")) == 60
