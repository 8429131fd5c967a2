"""SSL_T text and XML (thesis listings 4.2–4.6)."""

from __future__ import annotations

from dataclasses import replace
from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dkreason.errors import ParseError
from dkreason.model import TopicArg
from dkreason.parse.sslt import format_spec, format_xml, parse_text, parse_xml, read_specs

from .conftest import SCENARIOS

SPEC_FILES = sorted((SCENARIOS / "specs").glob("*.sslt")) if SCENARIOS else []


@pytest.mark.parametrize("path", SPEC_FILES, ids=lambda p: p.stem)
def test_text_and_xml_forms_of_every_thesis_spec_agree(path: Path) -> None:
    assert read_specs(path).specs == read_specs(path.with_suffix(".xml")).specs


@pytest.mark.parametrize("path", SPEC_FILES, ids=lambda p: p.stem)
def test_text_to_xml_to_text_round_trip_loses_nothing(path: Path) -> None:
    specs = read_specs(path).specs
    via_xml = parse_xml(format_xml(specs).encode()).specs
    assert via_xml == specs
    assert parse_text("\n".join(format_spec(s) for s in via_xml)).specs == specs


def test_for_entries_bind_by_name_not_position() -> None:
    (spec,) = parse_text(
        "topic topic7:UavMsg contains Close(uav2, uav1) = msg.close "
        "for uav1 = msg.id2, uav2 = msg.id1"
    ).specs
    assert [(a.name, a.id_field) for a in spec.features[0].args] == [
        ("uav2", "msg.id1"),
        ("uav1", "msg.id2"),
    ]


def test_aliases_tell_repeated_arguments_apart_and_survive_writing() -> None:
    text = (
        "topic t:M contains Close(UAV as a, UAV as b) = msg.c "
        "for every a = msg.id1, some b = msg.id2"
    )
    (spec,) = parse_text(text).specs
    assert spec.features[0].args == (
        TopicArg("every", "UAV", "msg.id1"),
        TopicArg("some", "UAV", "msg.id2"),
    )
    assert parse_text(format_spec(spec)).specs == (spec,)


def test_repeated_names_without_aliases_bind_in_order() -> None:
    (spec,) = parse_text(
        "topic t:M contains Behind(uav1, uav1) = msg.b for uav1 = msg.id1, uav1 = msg.id2"
    ).specs
    assert [a.id_field for a in spec.features[0].args] == ["msg.id1", "msg.id2"]


def test_several_features_per_topic_and_implicit_objects() -> None:
    (spec,) = parse_text(
        "topic t:M contains Altitude(uav1) = msg.alt, Speed(uav1) = msg.spd for uav1 = msg.id"
    ).specs
    assert [f.name for f in spec.features] == ["Altitude", "Speed"]
    assert spec.features[0].args[0].id_field is None
    assert spec.features[1].args[0].id_field == "msg.id"


def test_sort_and_object_topics_with_optional_sort_keyword() -> None:
    specs = parse_text(
        "topic a:M contains sort some UAV = msg.id\n"
        "topic b:M contains every UAV = msg.id\n"
        "topic c:M contains uav1 = msg.id"
    ).specs
    assert [(s.kind, s.entity.kind if s.entity else None) for s in specs] == [
        ("sort", "some"),
        ("sort", "every"),
        ("object", "object"),
    ]


def test_prefixed_names_iris_nested_fields_and_comments() -> None:
    (spec,) = parse_text(
        "# heading\ntopic t:M contains hr:Heading(<http://x.org/o#uav1>) "
        "= msg.pose.orientation.z for <http://x.org/o#uav1> = msg.ids[0]"
    ).specs
    arg = spec.features[0].args[0]
    assert (spec.features[0].name, arg.name, arg.id_field) == (
        "hr:Heading",
        "<http://x.org/o#uav1>",
        "msg.ids[0]",
    )


@pytest.mark.parametrize(
    ("text", "where", "says"),
    [
        ("topic t1:M contains Speed(uav1 = msg.spd", "x.sslt:1:32", "expected"),
        ("topic t1 M contains Speed(uav1) = msg.spd", "x.sslt:1:10", "expected ':'"),
        (
            "topic t1:M contains Speed(uav1) = msg.spd for uav2 = msg.id",
            "x.sslt:1:47",
            "names no unbound argument",
        ),
        (
            "topic t:M contains Speed(uav1) = msg.s\ntopic t:M contains Speed(uav1) = msg.s",
            "x.sslt:2:1",
            "specified twice",
        ),
    ],
)
def test_syntax_errors_name_file_line_column_and_what_was_expected(
    text: str, where: str, says: str
) -> None:
    with pytest.raises(ParseError) as err:
        parse_text(text, "x.sslt")
    assert str(err.value).startswith(where) and says in str(err.value)


@pytest.mark.parametrize(
    ("xml", "says"),
    [
        (
            b"<Topic_specs><Topic name='a' msgtype='b'><feature></Topic></Topic_specs>",
            "mismatched tag",
        ),
        (
            b"<Topic_specs><Topic name='a'><object name='x' value='f'/></Topic></Topic_specs>",
            "lacks the 'msgtype' attribute",
        ),
        (b"<Topics/>", "expected <Topic_specs>"),
        (
            b"<Topic_specs><Topic name='a' msgtype='M'><sort name='S' value='f' all_objects='yes'/>"
            b"</Topic></Topic_specs>",
            "all_objects must be true or false",
        ),
    ],
)
def test_malformed_xml_specs_are_rejected_with_their_line(xml: bytes, says: str) -> None:
    with pytest.raises(ParseError) as err:
        parse_xml(xml, "s.xml")
    assert str(err.value).startswith("s.xml:1") and says in str(err.value)


# ---- ROS names (issue 14) ----------------------------------------------------------------

ROS_SPECS = """topic /turtle1/pose:turtlesim/Pose contains X(turtle1) = msg.x
topic imu/data:sensor_msgs/msg/Imu contains Roll(imu1) = msg.orientation.x
topic /camera/imu/data:Imu contains Roll(imu2) = msg.orientation.x
topic "ORB-SLAM":orb_slam/msg/Pose contains X(cam1) = msg.x
topic topic1:UavMsg contains Altitude(uav1) = msg.alt for uav1 = msg.id
"""


def test_topic_names_are_ros_names_or_quoted_and_types_may_name_their_package() -> None:
    specs = parse_text(ROS_SPECS, "ros.sslt").specs
    assert [(s.name, s.msgtype) for s in specs] == [
        ("/turtle1/pose", "turtlesim/Pose"),
        ("imu/data", "sensor_msgs/msg/Imu"),
        ("/camera/imu/data", "Imu"),
        ("ORB-SLAM", "orb_slam/msg/Pose"),
        ("topic1", "UavMsg"),
    ]
    again = parse_text("".join(f"{format_spec(s)}\n" for s in specs), "again.sslt").specs
    via_xml = parse_xml(format_xml(specs).encode()).specs
    assert again == via_xml == specs


@pytest.mark.parametrize(
    ("line", "says"),
    [
        ("topic /a//b:T contains X(o) = msg.x", "ros.sslt:1:"),
        ("topic /a/:T contains X(o) = msg.x", "ros.sslt:1:"),
        ('topic "":T contains X(o) = msg.x', "an empty topic name"),
        ("topic a:pkg/msg/sub/T contains X(o) = msg.x", "ros.sslt:1:"),
    ],
)
def test_bad_ros_names_are_syntax_errors(line: str, says: str) -> None:
    with pytest.raises(ParseError, match=says):
        parse_text(line + "\n", "ros.sslt")


SSLT_KEYWORDS = ("some", "every", "sort", "for", "as", "contains", "topic")


@given(
    st.sampled_from(SSLT_KEYWORDS),
    st.from_regex(r"[A-Za-z0-9_]{1,6}", fullmatch=True),
)
@settings(max_examples=200, deadline=None)
def test_a_name_beginning_with_an_sslt_keyword_is_a_name(keyword: str, rest: str) -> None:
    """Issue 34, item 7: `someValue(uav1)` is a feature, not `some Value(…)`, wherever a
    name stands (feature, object, sort, alias)."""
    name = keyword + rest
    (spec,) = parse_text(
        f"topic t:M contains {name}(uav1) = msg.a, {name}({name} as {name}) = msg.b "
        f"for some {name} = msg.id, Other({name}) = msg.c for {name} = msg.id"
    ).specs
    assert [f.name for f in spec.features] == [name, name, "Other"]
    assert spec.features[1].args[0].name == name


# ---- declared stream quality (issue 31) ----------------------------------------------------


def test_a_topic_declares_its_rate_and_delay_in_a_bracket_after_the_message_type() -> None:
    text = (
        "topic topic1:UavMsg [rate 20 Hz, delay 50ms] contains Altitude(uav1) = msg.alt "
        "for uav1 = msg.id\n"
        "topic t2:M [delay 0.2] contains Speed(uav1) = msg.s\n"
        "topic t3:M [rate 0.5Hz] contains uav2 = msg.id\n"
        "topic t4:M contains Speed(uav2) = msg.s\n"
    )
    specs = parse_text(text, "q.sslt").specs
    assert [(s.rate, s.delay) for s in specs] == [
        (20, Fraction(1, 20)),
        (None, Fraction(1, 5)),
        (Fraction(1, 2), None),
        (None, None),
    ]
    assert format_spec(specs[0]).startswith("topic topic1:UavMsg [rate 20 Hz, delay 50ms] contains")
    assert format_spec(specs[3]) == "topic t4:M contains Speed(uav2) = msg.s"
    assert 'rate="20 Hz" delay="50ms"' in format_xml(specs)
    assert parse_xml(format_xml(specs).encode()).specs == specs
    assert parse_text("\n".join(map(format_spec, specs))).specs == specs


@settings(max_examples=60, deadline=None)
@given(
    rate=st.none() | st.decimals(min_value="0.001", max_value="100000", places=3),
    delay=st.none() | st.decimals(min_value="0", max_value="3600", places=4),
)
def test_declared_quality_survives_text_to_xml_to_text(
    rate: Decimal | None, delay: Decimal | None
) -> None:
    (spec,) = parse_text("topic t:M contains Speed(uav1) = msg.s").specs
    spec = replace(
        spec,
        rate=None if rate is None or rate <= 0 else Fraction(rate),
        delay=None if delay is None else Fraction(delay),
    )
    (via_xml,) = parse_xml(format_xml((spec,)).encode()).specs
    (back,) = parse_text(format_spec(via_xml)).specs
    assert (back.rate, back.delay) == (spec.rate, spec.delay)


@pytest.mark.parametrize(
    ("bracket", "where", "says"),
    [
        ("[rate fast]", "q.sslt:1:17", "rate 'fast' is not a rate in Hz"),
        ("[rate 0 Hz]", "q.sslt:1:17", "must be positive"),
        ("[delay -3ms]", "q.sslt:1:18", "delay '-3ms' is not a duration"),
        ("[delay 5 parsecs]", "q.sslt:1:18", "is not a duration"),
        ("[speed 3]", "q.sslt:1:12", "unknown stream property 'speed'"),
        ("[rate 3 Hz, rate 4 Hz]", "q.sslt:1:23", "rate is declared twice"),
        ("[rate]", "q.sslt:1:16", "expected a value, like 20 Hz or 50ms"),
        ("[]", "q.sslt:1:12", "expected a name"),
    ],
)
def test_a_bad_declared_property_is_one_line_naming_file_line_column(
    bracket: str, where: str, says: str
) -> None:
    with pytest.raises(ParseError) as err:
        parse_text(f"topic t:M {bracket} contains Speed(uav1) = msg.s", "q.sslt")
    assert str(err.value).startswith(where + ":") and says in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("bracket", "column"),
    [("[rate 20 Hz, delay 50ms", 34), ("[rate 20 Hz", 22), ("[delay 50ms\n ", 22)],
)
def test_a_bracket_of_stream_properties_left_open_says_where_its_bracket_belongs(
    bracket: str, column: int
) -> None:
    with pytest.raises(ParseError) as err:
        parse_text(f"topic t:M {bracket} contains Speed(uav1) = msg.s", "q.sslt")
    assert str(err.value) == f"q.sslt:1:{column}: missing ']' after the stream properties"


def test_a_bad_declared_property_in_xml_names_its_line() -> None:
    xml = b"<Topic_specs>\n<Topic name='a' msgtype='M' rate='-1 Hz'><object name='x' value='f'/>"
    with pytest.raises(ParseError, match=r"^s\.xml:2:.*rate '-1 Hz' must be positive"):
        parse_xml(xml + b"</Topic></Topic_specs>", "s.xml")
