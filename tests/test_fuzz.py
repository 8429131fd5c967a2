"""Property tests for everything that takes outside input: formulas, SSL_T, specs XML, configs,
JSON lines, live payloads and MCAP chunk headers give a result or one DkError line — never
another exception.

Examples are bounded (`max_examples`, sizes) so the suite stays within its time budget; the
strategies mix valid fragments with hostile ones so both paths are exercised."""

from __future__ import annotations

import contextlib
import math
import string
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from dkreason.errors import DkError, Span, WireError
from dkreason.inputs.files import json_value
from dkreason.live import wire
from dkreason.parse.config import read_config
from dkreason.parse.formula import parse_formula
from dkreason.parse.owl import parse_ontology
from dkreason.parse.owlsyntax import OWL_SYNTAXES, SYNTAXES, preamble_end, syntax
from dkreason.parse.sslt import parse_text, parse_xml
from dkreason.progress import Progressor
from dkreason.progress.statefile import read_states
from dkreason.stream.binding import open_recordings
from dkreason.stream.info import describe
from dkreason.stream.sources import JsonlSource

from .craft import Chunk, chunk_headers, rows
from .craft import write as craft

FAST = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

FORMULA_TOKENS = [
    "always",
    "eventually",
    "next",
    "historically",
    "once",
    "previous",
    "not",
    "and",
    "or",
    "->",
    "<->",
    "until",
    "since",
    "forall x in Car:",
    "exists y in UAV:",
    "(",
    ")",
    "[",
    "]",
    ",",
    "0",
    "1.5",
    "2e3",
    "inf",
    "oo",
    "300ms",
    "2min",
    "٣",
    "9" * 50,
    "X[a]",
    "P[x]",
    "Speed[car1]",
    ">",
    "<=",
    "==",
    "+",
    "-",
    "*",
    "/",
    "true",
    "false",
    "□",
    "◇",
    "∀",
    "<http://e.org/#A>",
]

SSLT_TOKENS = [
    "topic",
    "t1",
    "t2",
    ":",
    "Msg",
    "contains",
    "Speed",
    "(",
    ")",
    "car1",
    "=",
    "msg.spd",
    "msg.id",
    "for",
    "some",
    "every",
    "sort",
    "Car",
    ",",
    "as",
    "a1",
    "#c\n",
    "\n",
    "\r",
    "\x0c",
    "hr:Heading",
    "<http://e.org/#A>",
    "msg.a[1]",
]

JSON_PIECES = [
    '{"topic": "topic3", "time": 1, "msg": {"id": 1, "spd": 2}}',
    "{",
    "}",
    "[",
    "]",
    '"time"',
    ": ",
    "1e999999999",
    "NaN",
    "Infinity",
    "-0",
    '"x"',
    "null",
    "true",
    "9" * 5000,
    ",",
    '{"a":',
    "\xff",
    "\x00",
    '"values": {"P[a]": 1}',
]


def _total(call: Callable[..., Any], *args: Any) -> Any:
    """`call(*args)` returns or raises DkError — nothing else."""
    try:
        return call(*args)
    except DkError as exc:
        assert "\n" not in str(exc).strip() or str(exc).count("\n") <= 1
        return None


@FAST
@given(st.lists(st.sampled_from(FORMULA_TOKENS), max_size=40).map(" ".join))
def test_formulas(text: str) -> None:
    formula = _total(parse_formula, text)
    if formula is not None:
        progressor = Progressor()  # quantifiers need a knowledge base: one line each
        if _total(progressor.add, text) is None and not progressor.keys:
            return
        values = dict.fromkeys(progressor.keys, 1.0)
        _total(progressor.step, 0, values)
        _total(progressor.finish)


@FAST
@given(st.lists(st.sampled_from(SSLT_TOKENS), max_size=40).map(" ".join))
def test_sslt(text: str) -> None:
    _total(parse_text, text, "f.sslt")


XML_PIECES = [
    '<?xml version="1.0"?>',
    "<Topic_specs>",
    "</Topic_specs>",
    "<Topic_specs/>",
    '<Topic name="t" msgtype="M">',
    "</Topic>",
    '<feature name="F" value="msg.a">',
    "</feature>",
    '<object name="o" value="msg.id"/>',
    '<sort all_objects="true" name="S" value="msg.id"/>',
    "<!DOCTYPE r [",
    '<!ENTITY x SYSTEM "file:///etc/passwd">',
    "]>",
    "&x;",
    "&amp;",
    "<SSL/>",
]


@FAST
@given(st.lists(st.sampled_from(XML_PIECES), max_size=20).map("".join))
def test_specs_xml(text: str) -> None:
    _total(parse_xml, text.encode(), "f.xml")


CONFIG_PIECES = [
    'local = "p"\n',
    "[platforms.p]\n",
    'ontology = "o.owl"\n',
    'specs = "s.sslt"\n',
    "[[mappings]]\n",
    'source = "p"\n',
    'target = "q"\n',
    'file = "m.xml"\n',
    "mappings = 5\n",
    'rules = ["x.dl"]\n',
    "rules = [[[]]]\n",
    'ontology = "a\\u0000b"\n',
    "[platforms]\n",
    "x = {\n",
    "= 1\n",
]


@FAST
@given(st.lists(st.sampled_from(CONFIG_PIECES), max_size=12).map("".join))
def test_configs(tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    path = tmp_path_factory.mktemp("c") / "c.toml"
    path.write_text(text)
    _total(read_config, path)


@FAST
@given(
    st.lists(
        st.one_of(st.sampled_from(JSON_PIECES), st.text(string.printable, max_size=5)), max_size=12
    ).map("".join)
)
@example("1e" + "9" * 5000)
def test_json_lines(tmp_path_factory: pytest.TempPathFactory, line: str) -> None:
    folder = tmp_path_factory.mktemp("j")
    path = folder / "r.jsonl"
    path.write_bytes(line.encode("utf-8", "surrogateescape") + b"\n")
    _total(lambda: list(JsonlSource(path).records()))
    states = folder / "s.jsonl"
    states.write_bytes(line.encode("utf-8", "surrogateescape") + b"\n")
    _total(lambda: list(read_states(states)))


@FAST
@given(
    st.one_of(
        st.binary(max_size=200),
        st.lists(st.sampled_from(JSON_PIECES), max_size=12).map(
            lambda xs: "".join(xs).encode("utf-8", "surrogateescape")
        ),
    )
)
def test_live_payloads(payload: bytes) -> None:
    _total(wire.topic_message, payload, "p/t")
    _total(wire.decode, payload, wire.MAX_SAMPLE, "p/t")


@FAST
@given(
    st.one_of(
        st.binary(max_size=200),
        st.lists(st.sampled_from(JSON_PIECES), max_size=12).map(
            lambda xs: "".join(xs).encode("utf-8", "surrogateescape")
        ),
    )
)
def test_live_payloads_read_fast_or_not_read_as_before(payload: bytes) -> None:
    """orjson's reading of a peer's payload is json's (exact=False) wherever it reads one;
    what it refuses goes to json, so an error says what it said before."""
    before = _total(json_value, payload, Span("p/t"), False)
    with contextlib.suppress(DkError):
        assert _same(wire.decode(payload, wire.MAX_SAMPLE, "p/t"), before)


# ---- OWL's own syntaxes (issue 27): nesting of any depth, hostile preambles ---------------

NS = "http://x.org/s#"


def _nest(opening: str, closing: str, leaf: str = ":B") -> st.SearchStrategy[str]:
    """`depth` nested expressions: mostly shallow, now and then far past the bound."""
    depths = st.one_of(st.integers(0, 70), st.sampled_from([200, 3000, 20_000]))
    return depths.map(lambda d: opening * d + leaf + closing * d)


OFN_PIECES = st.one_of(
    st.sampled_from(
        [
            f"Prefix(:=<{NS}>)\n",
            f"Ontology(<{NS}>\n",
            ")",
            "(",
            "SubClassOf(:A ",
            "ObjectIntersectionOf(",
            "ObjectSomeValuesFrom(:p ",
            "ClassAssertion(:A :a)\n",
            "Declaration(Class(:A))\n",
            '"a (( \\" (("',
            '"',
            f"<{NS}A((>",
            "<",
            "# a comment ((\n",
            "\r",
            "\ufeff",
        ]
    ),
    _nest("ObjectIntersectionOf(:A ", ")"),
    _nest("(", ")"),
)
OMN_PIECES = st.one_of(
    st.sampled_from(
        [
            f"Prefix: : <{NS}>\n",
            f"Ontology: <{NS}>\n",
            "ObjectProperty: p\n",
            "Class: A\n",
            "Individual: a\n",
            " SubClassOf: ",
            " Types: ",
            "p some ",
            "p only ",
            "not ",
            " and ",
            " or ",
            "(",
            ")",
            "{a, b}",
            "inverse ",
            "p value a",
            "p min 1 ",
            "B",
            '"x ((("',
            "# note ((\n",
            "\n",
            "Types:",
        ]
    ),
    _nest("p some ", "", "B"),
    _nest("(", ")", "B"),
    _nest("not (", ")", "B"),
)
OWX_PIECES = st.one_of(
    st.sampled_from(
        [
            '<?xml version="1.0"?>',
            f'<!DOCTYPE Ontology [<!ENTITY s "{NS}">]>',
            '<Ontology xmlns="http://www.w3.org/2002/07/owl#">',
            "</Ontology>",
            "<SubClassOf>",
            "</SubClassOf>",
            '<Class IRI="&s;A"/>',
            f'<Class IRI="{NS}B"/>',
            "<ObjectIntersectionOf>",
            "</ObjectIntersectionOf>",
            "&s;",
            "&undefined;",
        ]
    ),
    _nest(
        "<ObjectIntersectionOf><Class IRI='x:A'/>", "</ObjectIntersectionOf>", "<Class IRI='x:B'/>"
    ),
)


@FAST
@given(
    st.sampled_from(["ofn", "omn", "owx"]).flatmap(
        lambda fmt: st.tuples(
            st.just(fmt),
            st.lists({"ofn": OFN_PIECES, "omn": OMN_PIECES, "owx": OWX_PIECES}[fmt], max_size=14),
            st.booleans(),
        )
    )
)
@example(("ofn", ["ObjectIntersectionOf(:A " * 10_000], True))
@example(
    ("omn", [f"Prefix: : <{NS}>\nOntology: <{NS}>\nClass: A SubClassOf: ", "(" * 10_000], False)
)
def test_owl_syntaxes_at_any_depth(case: tuple[str, list[str], bool]) -> None:
    """An ontology in OWL Functional, Manchester or OWL/XML syntax, named by its suffix or
    sniffed as .owl, of any depth: a result or one line, never a crash of the process."""
    fmt, pieces, sniffed = case
    _total(parse_ontology, "".join(pieces).encode(), "o.owl" if sniffed else f"o.{fmt}", "p")


PREAMBLE_PIECES = ["<!DOCTYPE x", "[", "]", '"', "'", "<!--", "-->", "<?xml ", "?>", ">", "#"]


@FAST
@given(
    st.lists(st.sampled_from([*PREAMBLE_PIECES, "\n", " ", "<Ontology>", "Prefix("]), max_size=30)
)
def test_a_preamble_of_any_shape_is_sniffed(pieces: list[str]) -> None:
    data = "".join(pieces).encode()
    assert 0 <= preamble_end(data) <= len(data)
    assert syntax(data, "o.owl") in SYNTAXES | OWL_SYNTAXES.keys()


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats() | st.text(),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(), inner, max_size=4),
    max_leaves=20,
)


@FAST
@given(JSON_VALUES)
def test_live_payloads_written_and_read_back(value: Any) -> None:
    """What a platform node writes, a monitor reads back: NaN and the infinities as null
    (unknown either way), lone surrogates and integers past 64 bits through json."""
    try:
        payload = wire.encode(value)
    except (UnicodeEncodeError, ValueError):  # a lone surrogate: json cannot write it either
        return
    assert _same(wire.decode(payload, 10**6, "p/t"), _finite(value))
    assert _same(json_value(payload, Span("p/t"), False), _finite(value))


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, list):
        return [_finite(v) for v in value]
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    return value


def _same(a: Any, b: Any) -> bool:
    """Equal, NaN equal to NaN, and of the same types (1 and 1.0 differ)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(st.data(), st.booleans())
def test_mcap_chunk_headers_described(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject, summary: bool
) -> None:
    """`dkreason info` over any chunk header (sizes to 2**64, CRCs, compressions misnamed or
    unknown, bytes cut short), indexed or read front to back: a description, its damage
    named, or one line; the counts never more than the chunks hold."""
    path = tmp_path_factory.mktemp("chunks") / "r.mcap"
    craft(
        path,
        [Chunk(rows(0, 5)), data.draw(chunk_headers(rows(10, 5))), Chunk(rows(20, 5))],
        summary,
    )
    recordings = _total(open_recordings, [path])
    if recordings is None:
        return
    try:
        info = _total(describe, recordings.parts[0])
    finally:
        recordings.close()
    if info is not None:
        (topic,) = info.topics
        assert topic.name == "/a" and topic.count is not None
        assert (10 if summary else 5) <= topic.count <= 15  # read around it, or up to it
        assert all("\n" not in d for d in info.damage)


def test_the_strategies_reach_valid_input() -> None:
    """The fuzzers are not only testing error paths."""
    assert parse_formula("always (X[a] > 1)")
    assert parse_text("topic t1:Msg contains Speed(car1) = msg.spd for car1 = msg.id")
    assert Path(__file__).exists()


def test_an_integer_past_64_bits_arrives_as_a_float_and_a_time_past_them_is_refused() -> None:
    assert wire.decode(b'{"x": 18446744073709551616}', 100, "p/t") == {"x": 2.0**64}
    with pytest.raises(WireError, match="integer nanoseconds"):
        wire.topic_message(b'{"valid": 100000000000000000000, "msg": {}}', "p/t")
