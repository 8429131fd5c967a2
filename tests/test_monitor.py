"""The Stream Processor and `dkreason monitor`, end to end, on recordings built here."""

from __future__ import annotations

import json
import shutil
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from dkreason import FeatureKey, KnowledgeManager
from dkreason.cli import main
from dkreason.errors import DkError
from dkreason.monitor import Event, Monitor
from dkreason.progress import Verdict
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.processor import Violation
from dkreason.stream.recording import write_recording
from dkreason.stream.sources import JsonlSource, PushSource, Source

REPO = Path(__file__).resolve().parents[1]
CAR = "dkreason_msgs/msg/CarMsg"
AUTO = "dkreason_msgs/msg/AutomobileMsg"
TYPES = {
    CAR: "int32 id\nfloat64 spd\n",
    AUTO: "std_msgs/Header header\nint32 id\nfloat64 speed\nfloat64 position\n",
}
S = 10**9
SPEEDING = "always (Speed[car1] > 60 -> eventually[0, 3] Speed[car1] <= 60)"
SLOW = "always (Speed[car2] < 60)"
CAR1, CAR2 = FeatureKey("Speed", ("car1",)), FeatureKey("Speed", ("car2",))


def car_rows(seconds: int = 8) -> Iterator[tuple[str, str, int, dict[str, Any]]]:
    """car2 keeps to 50; car1 speeds at 70 from 0.1 s to 5.1 s (a violation when the window
    [0.1, 3.1] closes)."""
    for t in range(seconds):
        yield ("/platform1/topic4", CAR, t * S, {"id": 2, "spd": 50.0})
        yield (
            "/platform1/topic3",
            CAR,
            t * S + S // 10,
            {"id": 1, "spd": 70.0 if t <= 5 else 50.0},
        )


def jsonl(path: Path, rows: Iterable[tuple[str, str, int, dict[str, Any]]]) -> Path:
    with path.open("w") as out:
        for topic, _, t_ns, msg in rows:
            out.write(
                json.dumps({"topic": topic.split("/")[-1], "time": t_ns / S, "msg": msg}) + "\n"
            )
    return path


@pytest.fixture(scope="module")
def single() -> KnowledgeManager:
    return KnowledgeManager.from_config(REPO / "examples" / "single.toml")


def run(
    capsys: pytest.CaptureFixture[str],
    config: Path,
    source: Path,
    *formulas: str,
    extra: Sequence[str] = (),
) -> tuple[int, list[dict[str, Any]]]:
    code = main(
        ["monitor", "--config", str(config), "--source", str(source), "--json", *extra, *formulas]
    )
    out = capsys.readouterr()
    return code, [json.loads(line) for line in out.out.splitlines()] + (
        [{"error": out.err.strip()}] if out.err.strip() else []
    )


@pytest.mark.parametrize("fmt", ["ros1", "sqlite3", "mcap", "bare-mcap", "jsonl"])
def test_every_recording_format_gives_the_same_verdicts(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, fmt: str
) -> None:
    if fmt == "jsonl":
        source = jsonl(tmp_path / "run.jsonl", car_rows())
    else:
        source = tmp_path / {"ros1": "run.bag", "bare-mcap": "run.mcap"}.get(fmt, "run")
        write_recording(source, fmt, TYPES, car_rows())  # type: ignore[arg-type]
    code, lines = run(capsys, REPO / "examples" / "single.toml", source, SPEEDING, SLOW)
    assert code == 1
    verdicts = {
        line["formula"]: (line["verdict"], line["time"], line["at_end"])
        for line in lines
        if "verdict" in line
    }
    # SLOW is judged on its own stream (car2's samples): it ends at 7 s, whatever runs beside it
    assert verdicts == {SPEEDING: (False, 3.1, False), SLOW: (True, 7, True)}


TRAFFIC = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)"


def test_traffic_example_federation_finds_car2s_violation_from_platform_2(
    capsys: pytest.CaptureFixture[str], traffic: Path, tmp_path: Path
) -> None:
    plot = tmp_path / "traffic.png"
    code, lines = run(
        capsys,
        REPO / "examples" / "federation.toml",
        traffic,
        TRAFFIC,
        extra=["--delay", "0.1", "--plot", str(plot)],
    )
    verdict, update = [line for line in lines if "verdict" in line]
    assert code == 1 and verdict["verdict"] is False and verdict["time"] == 300.02
    # car2's instance is judged from 0.01 s, its first speed; its window closes when the
    # formula's stream passes 300.01 s (car3's speed at 300.02 s)
    assert verdict["witness"] == (
        "c = car2 violated at t+300.02 s: Speed[car2] > 60 held at t+0.01 s, but "
        "Speed[car2] <= 60 never held within [t+0.01, t+300.01]"
    )
    assert [(i["bindings"], i["status"]) for i in verdict["instances"]] == [
        ({"c": "car1"}, "open"),
        ({"c": "car2"}, "violated"),
        ({"c": "car3"}, "open"),
    ]
    # the verdict stands; the instances open at it settle by the end
    assert update["update"] and (update["verdict"], update["time"]) == (False, 300.02)
    assert [(i["status"], i["time"]) for i in update["instances"]] == [
        ("held", 359),
        ("violated", 300.02),
        ("held", 359.02),
    ]
    assert not [line for line in lines if "violation" in line]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


PENDING = (
    "eventually[0, 300] Speed[car2] <= 60: window [t+60.01, t+360.01] cut off at the end of the "
    "data, 299.06 s of 300 s seen"
)


def test_traffic_example_single_platform_does_not_claim_what_it_did_not_see(
    capsys: pytest.CaptureFixture[str], traffic: Path
) -> None:
    code, lines = run(
        capsys, REPO / "examples" / "single.toml", traffic, TRAFFIC, extra=["--delay", "0.1"]
    )
    (verdict,) = [line for line in lines if "verdict" in line]
    assert code == 3 and verdict["verdict"] is None and verdict["at_end"] is True
    # car2 leaves platform 1's region after its speed at 199.01 s: silent from there to the
    # end of the recording, said once
    assert verdict["unknown"] == [
        {"feature": "Speed[car2]", "from": 199.01, "to": 359.07, "silent": True}
    ]
    assert verdict["witness"] == (
        "the data left it undecided for c = car2: Speed[car2] silent from t+199.01 s "
        f"(160.06 s before the end); {PENDING}"
    )
    assert [i["status"] for i in verdict["instances"]] == ["held", "unknown", "held"]
    (car2,) = [i for i in verdict["instances"] if i["status"] == "unknown"]
    assert car2["pending"] == PENDING


Row = tuple[str, float, dict[str, Any], float | None]  # topic, valid time, msg, available


# ---- stream constraints and bad samples ---------------------------------------------------


def messages(tmp_path: Path, rows: Sequence[Row]) -> Path:
    """JSON lines from (topic, valid time, msg, available time or None)."""
    path = tmp_path / "m.jsonl"
    with path.open("w") as out:
        for topic, t, msg, available in rows:
            row = {"topic": topic, "time": t, "msg": msg}
            if available is not None:
                row["available"] = available
            out.write(json.dumps(row) + "\n")
    return path


def events(
    single: KnowledgeManager,
    source: Path,
    policy: StreamPolicy,
    formula: str = "always (Speed[car1] > 0)",
) -> tuple[list[Event], Monitor]:
    monitor = Monitor(single.plan([formula]), single.request, policy, keep_states=True)
    return list(monitor.run(JsonlSource(source))), monitor


def kinds(evs: list[Event]) -> list[str]:
    return [e.constraint for e in evs if isinstance(e, Violation)]


def car1(t: float, spd: float = 50.0, available: float | None = None) -> Row:
    return ("topic3", t, {"id": 1, "spd": spd}, available)


def test_start_and_end_time_bound_what_is_judged_and_say_nothing_of_the_rest(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    """Samples outside the window are not the data asked about: skipped, not violations
    (issue 28: `--end +10` printed a violation for every later message)."""
    evs, monitor = events(
        single,
        messages(tmp_path, [car1(0), car1(1), car1(2), car1(3)]),
        StreamPolicy(start_time=Fraction(1), end_time=Fraction(2)),
    )
    assert kinds(evs) == []
    assert [t / S for t, _ in monitor.states] == [1, 2]


def test_sample_period_and_deviation(single: KnowledgeManager, tmp_path: Path) -> None:
    rows = [car1(0), car1(1), car1(2.05), car1(4)]
    evs, monitor = events(
        single,
        messages(tmp_path, rows),
        StreamPolicy(sample_period=Fraction(1), sample_period_deviation=Fraction(1, 10)),
    )
    (v,) = [e for e in evs if isinstance(e, Violation)]
    assert v.constraint == "sample_period" and "1.95 s since the previous sample" in v.detail
    assert [t / S for t, _ in monitor.states] == [0, 1, 2, 3, 4]


def test_max_delay(single: KnowledgeManager, tmp_path: Path) -> None:
    evs, _ = events(
        single,
        messages(tmp_path, [car1(0, available=0.1), car1(1, available=1.7)]),
        StreamPolicy(max_delay=Fraction(1, 2), delay_before_approximation=Fraction(1)),
    )
    (v,) = [e for e in evs if isinstance(e, Violation)]
    assert v.constraint == "max_delay" and "delay 0.7 s exceeds 0.5 s" in v.detail


def test_out_of_order_and_duplicate_samples(single: KnowledgeManager, tmp_path: Path) -> None:
    rows = [car1(0, 50, 0), car1(2, 52, 2), car1(1, 51, 2.1), car1(2, 53, 2.2)]
    evs, monitor = events(
        single,
        messages(tmp_path, rows),
        StreamPolicy(
            ordered_on_valid_time=True,
            unique_valid_time=True,
            delay_before_approximation=Fraction(1),
        ),
    )
    assert kinds(evs) == ["ordered_on_valid_time", "unique_valid_time"]
    # the out-of-order sample counts in valid-time order; on equal times the later arrival wins
    assert [(t / S, s[CAR1]) for t, s in monitor.states] == [(0, 50), (1, 51), (2, 53)]


def test_late_samples_are_reported_and_never_rewrite_states_already_made(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    rows = [car1(0, 50, 0), car1(1, 51, 1), car1(2, 52, 2), car1(0.5, 99, 2.5), car1(3, 53, 3)]
    evs, monitor = events(single, messages(tmp_path, rows), StreamPolicy(max_age=None))
    (v,) = [e for e in evs if isinstance(e, Violation)]
    assert v.constraint == "late" and "valid at 0.5 s arrived at 2.5 s" in v.detail
    assert [s[CAR1] for _, s in monitor.states] == [50, 51, 52, 53]


def test_missing_samples_make_values_unknown_and_no_violation_is_claimed(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    # car1 is seen speeding at 0 s and 1 s, then not for 29 s: the data cannot show whether
    # it slowed down within 20 s, so there is no violation, only an unknown span
    rows = [car1(0, 70), car1(1, 70), car1(30, 50)]
    evs, monitor = events(
        single,
        messages(tmp_path, rows),
        StreamPolicy(max_age=Fraction(2)),
        "always (Speed[car1] > 60 -> eventually[0, 20] Speed[car1] <= 60)",
    )
    (v,) = [e for e in evs if isinstance(e, Verdict)]
    assert v.verdict is None and v.at_end
    assert [(str(u.feature), u.start, u.end) for u in v.unknown] == [
        ("Speed[car1]", 3.000000001, 3.000000001)
    ]
    assert [(t / S, s[CAR1]) for t, s in monitor.states] == [
        (0, 70),
        (1, 70),
        (3.000000001, None),
        (30, 50),
    ]


def test_approximation_none_only_takes_samples_at_the_state_time(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    rows = [car1(0, 50), ("topic4", 0.5, {"id": 2, "spd": 40}, None), car1(1, 51)]
    evs, monitor = events(
        single,
        messages(tmp_path, rows),
        StreamPolicy(approximation="none"),
        "always (Speed[car1] > 0 and Speed[car2] > 0)",
    )
    assert [(t / S, s[CAR1], s[CAR2]) for t, s in monitor.states] == [
        (0, 50, None),
        (0.5, None, 40),
        (1, 51, None),
    ]


def test_filters_compare_ids_across_int_and_string(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    rows: list[Row] = [
        ("topic3", 0, {"id": "1", "spd": 70}, None),
        ("topic3", 1, {"id": 2, "spd": 10}, None),
        ("topic3", 2, {"id": 1, "spd": 30}, None),
    ]
    _, monitor = events(single, messages(tmp_path, rows), StreamPolicy(max_age=None))
    assert [s[CAR1] for _, s in monitor.states] == [70, 30]


def test_merge_prefers_the_most_recent_valid_time_then_the_local_platform(tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(REPO / "examples" / "federation.toml")
    rows = [
        ("topic3", 1, {"id": 1, "spd": 50}, None),
        ("platform2/carstopic2", 1, {"id": 11, "speed": 99}, 1.05),
        ("platform2/carstopic2", 2, {"id": 11, "speed": 61}, 2.05),
        ("topic3", 2.5, {"id": 1, "spd": 55}, None),
    ]
    monitor = Monitor(
        km.plan(["always (Speed[car1] > 0)"]),
        km.request,
        StreamPolicy(delay_before_approximation=Fraction(1, 10)),
        keep_states=True,
    )
    list(monitor.run(JsonlSource(messages(tmp_path, rows))))
    assert [(t / S, s[CAR1]) for t, s in monitor.states] == [(1, 50), (2, 61), (2.5, 55)]


def test_the_push_api_feeds_any_live_source(single: KnowledgeManager) -> None:
    source = PushSource()
    for t in range(5):
        source.push("topic3", t, {"id": 1, "spd": 70 if t < 4 else 50})
    source.end()
    monitor = Monitor(
        single.plan(["always (Speed[car1] > 60 -> eventually[0, 2] Speed[car1] <= 60)"]),
        single.request,
        StreamPolicy(),
    )
    (v,) = [e for e in monitor.run(source) if isinstance(e, Verdict)]
    assert (v.verdict, v.time) == (False, 2)


# ---- errors ---------------------------------------------------------------------------------


def test_a_field_missing_from_the_message_type_is_found_before_replay(
    single: KnowledgeManager, tmp_path: Path
) -> None:
    bag = tmp_path / "run.mcap"
    write_recording(
        bag,
        "bare-mcap",
        {CAR: "int32 id\nfloat64 speed\n"},
        [("/platform1/topic3", CAR, 0, {"id": 1, "speed": 3.0})],
    )
    with pytest.raises(
        DkError,
        match=r"topic /platform1/topic3 \(dkreason_msgs/msg/CarMsg\) "
        r"has no field msg.spd: .*has no field 'spd'",
    ):
        list(Monitor(single.plan([SPEEDING]), single.request, StreamPolicy()).run(_open(bag)))


def _open(path: Path) -> Source:
    from dkreason.stream.sources import open_source

    return open_source(path)


def test_a_truncated_recording_still_gives_what_was_decided_before_the_damage(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    bag = tmp_path / "cut.mcap"
    rows = [
        ("/platform1/topic3", CAR, t * S // 100, {"id": 1, "spd": 70.0 if t < 500 else 50.0})
        for t in range(60_000)
    ]
    write_recording(bag, "bare-mcap", TYPES, rows)
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])
    code, lines = run(capsys, REPO / "examples" / "single.toml", bag, SPEEDING)
    assert code == 2
    assert lines[0]["verdict"] is False and lines[0]["time"] == 3
    assert lines[-1]["error"].count("\n") == 1  # the note about reading sequentially, the error
    assert (
        f"error: {bag}: damaged recording: the file ends in the middle of a record"
        in lines[-1]["error"]
        and "messages before it were monitored" in lines[-1]["error"]
    )


@pytest.mark.parametrize("content", [b"not a bag at all", b""])
def test_an_unreadable_recording_is_a_one_line_error(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, content: bytes
) -> None:
    bag = tmp_path / "x.bag"
    bag.write_bytes(content)
    code = main(
        [
            "monitor",
            "--config",
            str(REPO / "examples" / "single.toml"),
            "--source",
            str(bag),
            SPEEDING,
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and f"{bag}: not a readable ROS recording" in err


def test_custom_message_definitions_are_read_from_msg_files(tmp_path: Path) -> None:
    msg = tmp_path / "dkreason_msgs" / "msg"
    msg.mkdir(parents=True)
    shutil.copy(
        REPO / "examples" / "traffic" / "msg" / "dkreason_msgs" / "msg" / "CarMsg.msg",
        msg / "CarMsg.msg",
    )
    from dkreason.stream.typestore import load_typestore, msg_types

    store = load_typestore(msg_types([msg / "CarMsg.msg"]), ros1=False)
    assert "dkreason_msgs/msg/CarMsg" in store.fielddefs
    with pytest.raises(DkError, match="expected a message definition pkg/msg/Name.msg"):
        msg_types([tmp_path / "CarMsg.txt"])


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("hello world\n", "field world has type 'hello', not a message type name"),
        ("lorem ipsum dolor sit amet\n", "field ipsum has type 'lorem', not a message type name"),
        ("import os\n", "field os has type 'import', not a message type name"),
        ("{\n", "Could not parse"),
    ],
)
def test_a_garbage_msg_file_is_refused_in_one_line_naming_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, traffic: Path, text: str, says: str
) -> None:
    """rosbags reads most text as some definition ("hello world": a field world of type
    hello); one that no ROS definition could be is refused, not used."""
    junk = tmp_path / "pkg" / "msg" / "Junk.msg"
    junk.parent.mkdir(parents=True)
    junk.write_text(text)
    config = str(REPO / "examples" / "federation.toml")
    argv = ["monitor", "--config", config, "--source", str(traffic), "--msg", str(junk)]
    code = main([*argv, "always (Speed[car1] < 90)"])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert out.err.startswith(f"error: {junk}: not a message definition (") and says in out.err
    assert out.err.count("\n") == 1


def test_a_msg_file_replaces_a_standard_definition_of_the_same_type(tmp_path: Path) -> None:
    """--msg std_msgs/msg/String.msg with another definition is that type's definition (as it
    replaces a recording's own), not rosbags' 'already present' error."""
    msg = tmp_path / "std_msgs" / "msg"
    msg.mkdir(parents=True)
    (msg / "String.msg").write_text("int32 data\n")
    from dkreason.stream.typestore import load_typestore, msg_types

    store = load_typestore(msg_types([msg / "String.msg"]), ros1=False)
    assert store.fielddefs["std_msgs/msg/String"][1][0][1][1][0] == "int32"


def test_a_recording_without_the_features_leaves_every_verdict_unknown(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    source = tmp_path / "other.jsonl"
    source.write_text('{"topic": "elsewhere", "time": 1, "msg": {}}\n')
    code, lines = run(
        capsys, REPO / "examples" / "single.toml", source, "always (Speed[car1] < 100)"
    )
    assert code == 3
    assert [(v["verdict"], v["time"]) for v in lines if "verdict" in v] == [(None, None)]
    argv = ["monitor", "--config", str(REPO / "examples" / "single.toml"), "--source", str(source)]
    assert main([*argv, "always (Speed[car1] < 100)"]) == 3
    out = capsys.readouterr().out.splitlines()
    (row,) = [x for x in out if x.startswith("│ always (Speed[car1]")]
    assert row.split("│")[3].strip() == "–"  # the summary's t (s): never decided, no time


# ---- one plan per formula, one monitor loop for every caller --------------------------------


def test_each_formula_is_parsed_once_and_expanded_once_from_the_cli_to_its_verdict(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, traffic: Path
) -> None:
    from dkreason import expand
    from dkreason.parse import formula

    counts: Counter[str] = Counter()
    parser, members = formula._PARSER, expand.members

    def parse(text: str, *args: Any, **kwargs: Any) -> Any:
        counts["parse"] += 1
        return type(parser).parse(parser, text, *args, **kwargs)

    def expanded(kb: Any, sorts: set[str]) -> dict[str, list[str]]:
        counts["expand"] += 1  # expand() asks for the members of its sorts once
        return members(kb, sorts)

    monkeypatch.setattr(parser, "parse", parse)
    monkeypatch.setattr(expand, "members", expanded)
    code, lines = run(
        capsys,
        REPO / "examples" / "federation.toml",
        traffic,
        TRAFFIC,
        "always (Position[car2] >= 0)",
        extra=["--delay", "0.1"],
    )
    assert code == 1 and [v["verdict"] for v in lines if "verdict" in v and "update" not in v] == [
        False,
        True,
    ]
    assert counts == {"parse": 2, "expand": 2}


def test_the_public_api_monitors_a_recording(traffic: Path) -> None:
    from dkreason import KnowledgeManager, StreamPolicy, Verdict, Violation

    km = KnowledgeManager.from_config(REPO / "examples" / "federation.toml")
    events = list(
        km.monitor(TRAFFIC, traffic, StreamPolicy(delay_before_approximation=Fraction(1, 10)))
    )
    verdicts = [e for e in events if isinstance(e, Verdict)]
    assert [(v.verdict, v.time, v.update) for v in verdicts] == [
        (False, 300.02, False),
        (False, 300.02, True),
    ]
    assert "Speed[car2]" in str(verdicts[0].witness)
    assert all(isinstance(e, Verdict | Violation) for e in events)


def test_a_stream_policy_is_keyword_only_and_immutable() -> None:
    with pytest.raises(TypeError):
        StreamPolicy(Fraction(1))  # type: ignore[call-arg]
    policy = StreamPolicy(max_age=Fraction(2))
    with pytest.raises(AttributeError):
        policy.max_age = Fraction(3)  # type: ignore[misc]


# ---- a formula's verdict does not depend on the formulas beside it ---------------------------

POOL = [
    "always (Speed[car1] < 80)",
    "eventually[0, 1.5] Speed[car2] > 60",
    "always (Speed[car1] > 60 -> eventually[0, 1] Speed[car1] <= 60)",
    "next (Speed[car3] > 50)",
    "always[0, 2] (Speed[car2] + Speed[car3] < 150)",
    "(Speed[car1] < 70) until[0, 3] (Speed[car3] > 70)",
    "historically[0, 1] Speed[car2] < 90",
    "forall c in Car: always (Speed[c] >= 0)",
]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(
            st.sampled_from([1, 2, 3]),
            st.integers(0, 40),
            st.sampled_from([10.0, 55.0, 65.0, 85.0]),
        ),
        min_size=1,
        max_size=40,
    ),
    st.sampled_from(POOL),
    st.lists(st.sampled_from(POOL), max_size=4),
)
def test_a_formulas_verdict_alone_equals_its_verdict_beside_others(
    single: KnowledgeManager, samples: list[tuple[int, int, float]], formula: str, others: list[str]
) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        # every car is seen first at 0: witnesses count `t+` from the first sample the
        # formulas read, the same whatever runs beside (until `t` counts from the recording)
        first = [(car, 0, 50.0) for car in (1, 2, 3)]
        rows: list[Row] = [
            (f"topic{car + 2}", tick / 10, {"id": car, "spd": speed}, None)
            for car, tick, speed in sorted(first + sorted(set(samples)), key=lambda r: r[1])
        ]
        source = messages(Path(tmp), rows)
        policy = StreamPolicy(max_age=Fraction(2))

        def verdict(formulas: list[str]) -> Any:
            events = list(
                Monitor(single.plan(formulas), single.request, policy).run(JsonlSource(source))
            )
            return next(
                (e.verdict, e.time, e.witness)
                for e in events
                if isinstance(e, Verdict) and e.formula == formula
            )

        assert verdict([formula]) == verdict([*others, formula, *others])


# ---- states made from what changed equal states read in full -------------------------------

MERGED = "always (Speed[car1] + Speed[car2] + Speed[car3] + Altitude[uav1] < 1000)"
FEEDS = {"topic1": 1, "topic2": 1, "topic3": 1, "topic4": 2, "topic5": 3}  # topic → its id


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(
            st.sampled_from(sorted(FEEDS)),
            st.integers(0, 30),
            st.integers(0, 8),
            st.sampled_from([10.0, 55.0, 70.0, float("nan")]),
        ),
        max_size=50,
    ),
    st.sampled_from([None, Fraction(1, 2), Fraction(3)]),
    st.sampled_from([Fraction(0), Fraction(1, 5)]),
    st.booleans(),
    st.sampled_from([(None, None), (Fraction(1, 2), None), (None, Fraction(2))]),
)
@example(  # a late sample of car1 goes stale at the instant car2 does
    [
        ("topic1", 0, 0, 10.0),
        ("topic3", 1, 7, 10.0),
        ("topic3", 7, 0, 10.0),
        ("topic4", 1, 0, 10.0),
    ],
    Fraction(1, 2),
    Fraction(1, 5),
    False,
    (None, None),
)
def test_states_made_from_what_changed_equal_states_read_in_full(
    single: KnowledgeManager,
    samples: list[tuple[str, int, int, float]],
    max_age: Fraction | None,
    delay: Fraction,
    ordered: bool,
    span: tuple[Fraction | None, Fraction | None],
) -> None:
    """A state on every change reads only the features sampled at it, reached by a late
    sample or expired at it; whatever the arrival order (late samples, equal times, a
    feature fed by two topics, values gone stale, samples outside the span dropped), its
    states are those of reading every feature's history at every state."""
    policy = StreamPolicy(
        max_age=max_age,
        delay_before_approximation=delay,
        ordered_on_valid_time=ordered,
        start_time=span[0],
        end_time=span[1],
    )
    arrivals = sorted(
        ((valid + lag) * S // 10, valid * S // 10, topic, speed)
        for topic, valid, lag, speed in samples
    )

    def states(incremental: bool) -> list[Any]:
        out: list[Any] = []
        monitor = Monitor(single.plan([MERGED]), single.request, policy)
        processor = monitor.start(PushSource())
        processor.incremental = incremental
        processor.on_state = lambda s, values, fresh: out.append(
            (s, dict(values), None if fresh is None else sorted(set(fresh)))
        )
        processor.on_violation = lambda v: out.append(v)
        try:
            for _ in processor.replay(
                (topic, available, valid, (speed, FEEDS[topic]))
                for available, valid, topic, speed in arrivals
            ):
                pass
        except DkError as exc:  # the window ended before the first sample arrived
            out.append(str(exc))
        processor.finish()
        return out

    assert states(True) == states(False)


@pytest.mark.parametrize("from_first", [False, True])
def test_periodic_states_from_a_start_time_are_made_as_the_data_passes_them(
    single: KnowledgeManager, from_first: bool
) -> None:
    """With a sample period and a start time (absolute, or counted from the first sample),
    a violation is reported when the recording has passed it, not only at the end."""
    policy = StreamPolicy(
        sample_period=Fraction(1), start_time=Fraction(0), span_from_start=from_first
    )
    monitor = Monitor(single.plan(["always (Speed[car1] > 20)"]), single.request, policy)
    processor = monitor.start(PushSource())
    origin = 100 * S if from_first else 0
    messages = [
        ("topic3", origin + k * S, origin + k * S, (30.0 if k < 5 else 10.0, 1)) for k in range(10)
    ]
    seen: list[Event] = []
    for _ in processor.replay(iter(messages), monitor.pending):
        seen += monitor.events()
    assert [(e.verdict, e.time) for e in seen if isinstance(e, Verdict)] == [
        (False, (origin + 5 * S) / S)
    ]
