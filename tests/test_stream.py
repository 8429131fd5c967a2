"""Stream sources: fields read straight from serialised messages equal full deserialisation;
the stream policy, checked when made (and on the command line, one line each); a sample
period bounded by the span it would fill with states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.typesys.store import Typestore

from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.stream.fastread import compile_extractor
from dkreason.stream.fields import accessor, check
from dkreason.stream.pace import paced
from dkreason.stream.units import NS

DEFINITION = (
    "std_msgs/Header header\nint32 id\nfloat64 speed\nuint8[4] arr\nstring name\n"
    "bool flag\nint64 big\ngeometry_msgs/Point where\nfloat64[] tail\nint8 last"
)
FIELDS = [
    "msg.speed",
    "msg.id",
    "msg.header.stamp.sec",
    "msg.header.stamp.nanosec",
    "msg.arr[2]",
    "msg.name",
    "msg.flag",
    "msg.big",
    "msg.where.z",
    "msg.header.frame_id",
]
# no header: the fields before the string are all at offsets known beforehand
HEADLESS = "int8 tag\nuint16[3] arr\nfloat64 speed\nbool flag\nstring name\nint32 after"
HEADLESS_FIELDS = [
    "msg.tag",
    "msg.arr[0]",
    "msg.arr[2]",
    "msg.speed",
    "msg.flag",
    "msg.name",
    "msg.after",
]


def store(ros1: bool) -> Typestore:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg(DEFINITION, "x/msg/T"))
    ts.register(get_types_from_msg(HEADLESS, "x/msg/U"))
    return ts


STORES = {ros1: store(ros1) for ros1 in (False, True)}


@settings(max_examples=150, deadline=None)
@given(
    ros1=st.booleans(),
    frame=st.text(max_size=5),
    name=st.text(max_size=7),
    sec=st.integers(0, 2**31 - 1),
    nsec=st.integers(0, 10**9 - 1),
    ident=st.integers(-(2**31), 2**31 - 1),
    speed=st.floats(allow_nan=False),
    arr=st.lists(st.integers(0, 255), min_size=4, max_size=4),
    flag=st.booleans(),
    big=st.integers(-(2**63), 2**63 - 1),
    z=st.floats(allow_nan=False),
    fields=st.one_of(st.just(FIELDS), st.lists(st.sampled_from(FIELDS), min_size=1, max_size=4)),
)
def test_extracted_fields_equal_full_deserialisation(
    ros1: bool,
    frame: str,
    name: str,
    sec: int,
    nsec: int,
    ident: int,
    speed: float,
    arr: list[int],
    flag: bool,
    big: int,
    z: float,
    fields: list[str],
) -> None:
    """Any fields, in any order, some asked twice: those before a string are read at offsets
    known beforehand, the others as the message is read."""
    ts = STORES[ros1]
    header = {"seq": 7} if ros1 else {}
    msg = ts.types["x/msg/T"](
        header=ts.types["std_msgs/msg/Header"](
            stamp=ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
            frame_id=frame,
            **header,
        ),
        id=ident,
        speed=speed,
        arr=np.array(arr, dtype=np.uint8),
        name=name,
        flag=flag,
        big=big,
        where=ts.types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=z),
        tail=np.array([1.5]),
        last=3,
    )
    raw = bytes((ts.serialize_ros1 if ros1 else ts.serialize_cdr)(msg, "x/msg/T"))
    extract = compile_extractor(ts.fielddefs, "x/msg/T", fields, ros1)
    assert extract is not None
    back = (ts.deserialize_ros1 if ros1 else ts.deserialize_cdr)(raw, "x/msg/T")
    want = tuple(
        v.item() if hasattr(v, "item") else v
        for v in (accessor(f, dicts=False)(back) for f in fields)
    )
    assert extract(raw) == want


@settings(max_examples=100, deadline=None)
@given(
    ros1=st.booleans(),
    tag=st.integers(-128, 127),
    arr=st.lists(st.integers(0, 2**16 - 1), min_size=3, max_size=3),
    speed=st.floats(allow_nan=False),
    flag=st.booleans(),
    name=st.text(max_size=7),
    after=st.integers(-(2**31), 2**31 - 1),
    fields=st.lists(st.sampled_from(HEADLESS_FIELDS), min_size=1, max_size=5),
)
def test_fields_at_known_offsets_are_read_in_one_call(
    ros1: bool,
    tag: int,
    arr: list[int],
    speed: float,
    flag: bool,
    name: str,
    after: int,
    fields: list[str],
) -> None:
    ts = STORES[ros1]
    msg = ts.types["x/msg/U"](
        tag=tag, arr=np.array(arr, dtype=np.uint16), speed=speed, flag=flag, name=name, after=after
    )
    raw = bytes((ts.serialize_ros1 if ros1 else ts.serialize_cdr)(msg, "x/msg/U"))
    extract = compile_extractor(ts.fielddefs, "x/msg/U", fields, ros1)
    assert extract is not None
    back = (ts.deserialize_ros1 if ros1 else ts.deserialize_cdr)(raw, "x/msg/U")
    assert extract(raw) == tuple(
        v.item() if hasattr(v, "item") else v
        for v in (accessor(f, dicts=False)(back) for f in fields)
    )


@pytest.mark.parametrize("ros1", [False, True])
def test_layouts_it_cannot_read_fall_back_to_deserialisation(ros1: bool) -> None:
    ts = STORES[ros1]
    assert compile_extractor(ts.fielddefs, "x/msg/T", ["msg.last"], ros1) is None  # after tail
    assert compile_extractor(ts.fielddefs, "x/msg/T", ["msg.nope"], ros1) is None


def test_big_endian_cdr_is_left_to_the_deserialiser() -> None:
    ts = STORES[False]
    extract = compile_extractor(ts.fielddefs, "x/msg/T", ["msg.id"], False)
    assert extract is not None and extract(bytes([0, 0, 0, 0]) + bytes(64)) is None


@pytest.mark.parametrize(
    ("field", "says"),
    [
        ("msg.speed.x", "has no fields"),
        ("msg.arr.x", "has no fields"),
        ("msg.speed[1]", "is not an array"),
        ("msg.nope", "x/msg/T has no field 'nope'"),
    ],
)
def test_field_checks_say_why(field: str, says: str) -> None:
    assert says in (check(STORES[False].fielddefs, "x/msg/T", field) or "")


# ---- the stream policy: checked when made, with the CLI's defaults ---------------------------


def test_a_stream_policy_takes_durations_as_numbers_or_unit_text() -> None:
    from fractions import Fraction

    from dkreason import StreamPolicy

    policy = StreamPolicy(max_age="500ms", sample_period=0.1, delay_before_approximation="2 min")
    assert (policy.max_age, policy.sample_period) == (Fraction(1, 2), Fraction(1, 10))
    assert policy.delay_before_approximation == 120
    assert StreamPolicy(start_time="-1.5", end_time=3).start_time == Fraction(-3, 2)


def test_the_api_and_the_cli_share_the_stream_policys_defaults() -> None:
    from fractions import Fraction

    from dkreason import StreamPolicy
    from dkreason.cli.options import policy
    from dkreason.cli.parser import build

    args = build(None).parse_args(["monitor", "--config", "c.toml", "--source", "r", "F"])
    assert policy(args) == StreamPolicy()
    assert StreamPolicy().delay_before_approximation == Fraction(1, 10)  # the CLI's 100 ms


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("max_age", "500 parsecs", "max_age: '500 parsecs' is not a duration"),
        ("delay_before_approximation", -1, "delay_before_approximation must not be negative"),
        ("sample_period", 0, "sample_period must be positive"),
        ("approximation", "latest", "approximation: 'latest' is not one of recent, none"),
        ("max_delay", float("nan"), "max_delay must be finite"),
        ("ordered_on_valid_time", "yes", "ordered_on_valid_time must be True or False"),
    ],
)
def test_a_bad_stream_policy_field_is_one_error_naming_it(
    field: str, value: object, message: str
) -> None:
    from dkreason import StreamPolicy

    with pytest.raises(DkError, match=message):
        StreamPolicy(**{field: value})  # type: ignore[arg-type]


def test_an_end_before_the_start_is_refused_when_the_policy_is_made() -> None:
    from dkreason import StreamPolicy

    with pytest.raises(DkError, match="end_time 50 is before start_time 100"):
        StreamPolicy(start_time=100, end_time=50)


FEDERATION = str(Path(__file__).resolve().parents[1] / "examples" / "federation.toml")


@pytest.mark.parametrize(
    ("options", "says"),
    [
        (["--start", "100", "--end", "50"], "StreamPolicy end_time 50 is before start_time 100"),
        (
            ["--remap", "/a:=/x", "--remap", "/a:=/y"],
            "--remap '/a:=/y': /a is already remapped to /x",
        ),
    ],
)
def test_contradictory_options_on_the_command_line_are_one_line_exit_2(
    capsys: pytest.CaptureFixture[str], traffic: Path, options: list[str], says: str
) -> None:
    argv = ["monitor", "--config", FEDERATION, "--source", str(traffic), *options]
    code = main([*argv, "--json", "always (Speed[car1] < 90)"])
    out = capsys.readouterr()
    assert code == 2 and out.out == "" and out.err == f"error: {says}\n"


def test_a_period_too_fine_for_the_recordings_span_is_one_line_before_any_state(
    capsys: pytest.CaptureFixture[str], traffic: Path
) -> None:
    """`--period 1e-9` over the 359 s traffic recording would make 3.6e11 states (it ran
    forever): the count is known from the recording's span before the first state."""
    from dkreason import KnowledgeManager, StreamPolicy

    km = KnowledgeManager.from_config(FEDERATION)
    run = km.monitor(
        "always (Speed[car1] < 90)", [traffic], StreamPolicy(sample_period="1e-9"), keep_states=True
    )
    with pytest.raises(DkError) as error:
        list(run)
    assert run.states == []
    assert str(error.value) == (
        "--period 1e-09 s over 359.07 s would make 3.6e11 states (at most 10,000,000): give "
        "a longer period, or a shorter span (--start, --end)"
    )
    argv = ["monitor", "--config", FEDERATION, "--source", str(traffic), "--period", "1e-9"]
    code = main([*argv, "--json", "always (Speed[car1] < 90)"])
    out = capsys.readouterr()
    assert code == 2 and out.out == "" and out.err.endswith(f"\nerror: {error.value}\n")


def test_without_a_known_end_the_period_is_bounded_at_each_advance(tmp_path: Path) -> None:
    """JSON lines say nothing of their end before they are read: the states one advance of
    the stream would make are counted before they are made."""
    from dkreason import KnowledgeManager, StreamPolicy

    lines = tmp_path / "r.jsonl"
    lines.write_text(
        "".join(
            f'{{"topic": "topic3", "time": {t}, "msg": {{"id": 1, "spd": 50}}}}\n' for t in (0, 330)
        )
    )
    km = KnowledgeManager.from_config(FEDERATION)
    policy = StreamPolicy(sample_period="1e-9", delay_before_approximation=0)
    run = km.monitor("always (Speed[car1] < 90)", [lines], policy, keep_states=True)
    with pytest.raises(DkError, match=r"over 330 s would make 3.3e11 states \(at most"):
        list(run)
    assert run.states == []


def test_pushed_times_are_seconds_and_nanoseconds_are_caught() -> None:
    from dkreason import PushSource

    source = PushSource()
    source.push("topic3", 1.5, {"id": 1, "spd": 70})
    with pytest.raises(DkError, match="times are seconds .nanoseconds given"):
        source.push("topic3", 1_700_000_000_000_000_000, {"id": 1, "spd": 70})


@given(
    st.lists(st.integers(0, 10 * NS), min_size=1, max_size=20).map(sorted),
    st.sampled_from([0.5, 1.0, 4.0]),
)
def test_a_paced_replay_yields_each_message_when_its_record_time_comes(
    times: list[int], speed: float
) -> None:
    """`--speed`: a message recorded t s after the first is read t / speed s after it (the
    clock is the test's: nothing sleeps)."""
    now = [0.0]

    def sleep(seconds: float) -> None:
        assert seconds > 0
        now[0] += seconds

    messages = iter([("/a", t, t, ()) for t in times])
    for message in paced(messages, speed, clock=lambda: now[0], sleep=sleep):
        assert now[0] == pytest.approx((message[1] - times[0]) / NS / speed)
