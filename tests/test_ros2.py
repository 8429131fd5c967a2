"""Live ROS 2 robots over Zenoh (issue 17): rmw_zenoh's and zenoh-bridge-ros2dds' wire formats,
discovery, binding, decoding, and what a careless or hostile peer sends.

Everything runs on loopback in this process (127.0.0.1, explicit endpoints); the publishers
speak the wire formats from Python (dkreason.live.ros2node, dkreason.live.testing).  Tests
that judge times run on sim time (/clock), which the test drives, so no verdict depends on the
machine's speed; waits are bounds on failure only.
"""

from __future__ import annotations

import functools
import itertools
import json
import logging
import struct
import threading
import time
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.errors import WireError
from dkreason.live import rmw
from dkreason.live.change import Change
from dkreason.live.publish import Announcer
from dkreason.live.record import Recorder
from dkreason.live.rmw import CLOCK_TYPE
from dkreason.live.ros2 import Ros2Monitor, decode, held
from dkreason.live.ros2node import Ros2Node
from dkreason.live.session import open_session
from dkreason.live.testing import cdr_clock, replay
from dkreason.monitor import Monitor
from dkreason.progress import Verdict
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.processor import Violation
from dkreason.stream.sources import RosbagSource
from dkreason.stream.typestore import load_typestore, msg_types, ros_reader

from .conftest import REPO
from .test_live import POSITION, SPEEDING, free_port

S = 10**9
POSE = "geometry_msgs/msg/PoseStamped"
TRAFFIC_MSGS = sorted((REPO / "examples" / "traffic" / "msg").rglob("*.msg"))
TRAFFIC_TOPICS = [
    "/clock",
    "/platform1/topic3",
    "/platform1/topic4",
    "/platform1/topic5",
    "/platform2/carstopic1",
    "/platform2/carstopic3",
]  # what the formulas read
TALKER = (
    "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
    "std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503"
    "259e948f6b1a18/::,7:,:,:,,"
)


# ---- the wire formats -------------------------------------------------------------------


def test_an_rmw_zenoh_publisher_token_names_topic_type_node_and_data_key() -> None:
    pub = rmw.parse_token(TALKER)
    assert pub is not None
    assert (pub.topic, pub.msgtype, pub.node, pub.namespace, pub.domain, pub.bridged) == (
        "/chatter",
        "std_msgs/msg/String",
        "talker",
        "/",
        2,
        False,
    )
    assert pub.key == (
        "2/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a7"
        "0dfd4bd59db1288021743503259e948f6b1a18"
    )
    robot = rmw.parse_token(
        "@ros2_lv/0/aa/3/12/MP/%/%robot1/odometry/%robot1%odom/"
        "nav_msgs::msg::dds_::Odometry_/RIHS01_00/::,10:,:,:,,"
    )
    assert robot is not None
    assert (robot.topic, robot.namespace, robot.key) == (
        "/robot1/odom",
        "/robot1",
        "0/robot1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_00",
    )


def test_other_entities_are_not_publishers_and_a_bridge_token_is_read_too() -> None:
    node = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    sub = TALKER.replace("/MP/", "/MS/")
    assert rmw.parse_token(node) is None and rmw.parse_token(sub) is None
    assert (
        rmw.parse_token("@ros2_lv/7f3a/SS/add_two_ints/example_interfaces§srv§AddTwoInts") is None
    )
    bridged = rmw.parse_token("@ros2_lv/7f3a/MP/robot2§odom/nav_msgs§msg§Odometry/K:1::1,5")
    assert bridged is not None
    assert (bridged.topic, bridged.msgtype, bridged.key, bridged.bridged, bridged.node) == (
        "/robot2/odom",
        "nav_msgs/msg/Odometry",
        "robot2/odom",
        True,
        None,
    )
    assert rmw.parse_token(
        rmw.bridge_token("7f3a", "/robot2/odom", "nav_msgs/msg/Odometry")
    ) == bridged.__class__(
        rmw.bridge_token("7f3a", "/robot2/odom", "nav_msgs/msg/Odometry"),
        "/robot2/odom",
        "nav_msgs/msg/Odometry",
        "robot2/odom",
        None,
        None,
        None,
        True,
    )


@pytest.mark.parametrize(
    "token",
    [
        "@ros2_lv/x/aa/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/h/q",  # domain
        "@ros2_lv/0/aa/0/10/MP/%/%/talker/%chatter/String/h/q",  # not a DDS type name
        "@ros2_lv/0/aa/0/10/MP/%/%/talker/%chatter",  # cut short
        "@ros2_lv/0/aa/0/10/MP/%/%/talker/%chat ter/std_msgs::msg::dds_::String_/h/q",  # name
        "@ros2_lv/0/aa/0/10/ZZ/%/%/talker",  # no such entity
        "@ros2_lv/7f3a/MP/robot2§odom/Odometry/q",  # bridge: not a ROS type
        "@ros2_lv/" + "a/" * 3000,  # too long
        "@ros2_lv/0/aa/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/**/q",  # wildcard
    ],
)
def test_a_malformed_token_is_a_wire_error(token: str) -> None:
    with pytest.raises(WireError):
        rmw.parse_token(token)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.sampled_from(
            [
                "@ros2_lv",
                "0",
                "MP",
                "NN",
                "%",
                "%a%b",
                "x::msg::dds_::Y_",
                "a§b",
                "::,7:,:,:,,",
                "",
                "ü",
                "12",
                "/",
                "q",
            ]
        ),
        max_size=15,
    )
)
def test_any_token_is_a_publisher_none_or_a_wire_error(parts: list[str]) -> None:
    try:
        pub = rmw.parse_token("/".join(parts))
    except WireError:
        return
    assert pub is None or (pub.topic.startswith("/") and "/" in pub.msgtype)


def test_attachments_of_both_layouts_are_read() -> None:
    gid = bytes(range(1, 17))
    plain = rmw.attachment(9, 1_788_000_000_123_456_789, gid)
    assert len(plain) == 33 and plain[16] == 16
    assert rmw.parse_attachment(plain) == (9, 1_788_000_000_123_456_789, gid)
    labelled = b"".join(
        bytes([len(label)]) + label + value
        for label, value in (
            (b"sequence_number", struct.pack("<q", 42)),
            (b"source_timestamp", struct.pack("<q", 1_700_000_000_000_000_000)),
            (b"source_gid", b"\x10" + gid),
        )
    )
    assert rmw.parse_attachment(labelled) == (42, 1_700_000_000_000_000_000, gid)
    assert rmw.attachment(42, 1_700_000_000_000_000_000, gid, labelled=True) == labelled


@given(st.binary(max_size=100))
def test_any_attachment_bytes_are_read_or_refused(data: bytes) -> None:
    try:
        sequence, stamp, gid = rmw.parse_attachment(data)
    except WireError:
        return
    assert len(gid) == 16 and rmw.attachment(sequence, stamp, gid) == data or len(data) == 77


@given(
    st.integers(-(2**63), 2**63 - 1),
    st.integers(-(2**63), 2**63 - 1),
    st.binary(min_size=16, max_size=16),
)
def test_attachments_round_trip(sequence: int, stamp: int, gid: bytes) -> None:
    assert rmw.parse_attachment(rmw.attachment(sequence, stamp, gid)) == (sequence, stamp, gid)


def test_type_names_map_both_ways_and_payloads_must_be_cdr() -> None:
    assert rmw.dds_type("nav_msgs/msg/Odometry") == "nav_msgs::msg::dds_::Odometry_"
    assert rmw.ros_type("nav_msgs::msg::dds_::Odometry_") == "nav_msgs/msg/Odometry"
    rmw.check_cdr(b"\x00\x01\x00\x00abcd", 100)
    for bad, kind in ((b'{"x": 1}', "cdr"), (b"\x00", "cdr"), (b"\x00\x01" + bytes(200), "size")):
        with pytest.raises(WireError) as caught:
            rmw.check_cdr(bad, 100)
        assert caught.value.kind == kind


def test_on_the_wall_clock_a_topic_holds_states_back_as_far_as_its_samples_lag() -> None:
    """A publisher's samples come in order, each about as late as the last: states wait for a
    congested topic's backlog (its samples are not made late), not for a slow topic on a
    healthy link, and for no topic more than a second, nor for one silent that long."""
    now, ms = 100 * S, S // 1000
    assert held(now, []) == now
    healthy_slow = (now - 900 * ms, now - 901 * ms, ms)  # 1 Hz, its last sample 1 ms late
    assert held(now, [healthy_slow]) == now - ms
    congested = (now, now - 500 * ms, 500 * ms)  # samples arrive half a second late
    assert held(now, [congested]) == now - 500 * ms
    assert held(now, [(now - 2 * S, now - 5 * S, 3 * S)]) == now  # silent for 2 s
    assert held(now, [(now, now - 30 * S, 30 * S)]) == now - S  # a clock 30 s behind: 1 s
    ahead = (now - 10 * ms, now + 5 * S, -5 * S)  # a clock ahead: nothing to wait for
    assert held(now, [healthy_slow, congested, ahead]) == now - 500 * ms


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=120), st.sampled_from([b"\x00\x01\x00\x00", b"\x00\x00\x00\x00"]))
def test_any_payload_decodes_to_the_wanted_values_or_is_a_wire_error(
    body: bytes, header: bytes
) -> None:
    """What a peer puts on a subscribed key: read field by field, or decoded in full (a
    topic's first message), either gives values or a WireError, in either byte order."""
    read, stamped = ros_reader(
        STORE.fielddefs, POSE, ["msg.pose.position.x"], False, STORE.deserialize_cdr
    )
    payload = header + body
    for reader in (read, lambda raw: STORE.deserialize_cdr(raw, POSE)):
        try:
            decode(reader, payload, POSE)
        except WireError as exc:
            assert exc.kind == "decode"
    good = pose(STORE, 3 * S, 1.5)
    assert decode(read, good, POSE) == (1.5, 3, 0) and stamped


# ---- live, on loopback --------------------------------------------------------------------


@pytest.fixture
def robots(tmp_path: Path) -> Path:
    """Two robots of one fleet, each under its namespace, reading a standard stamped type."""
    (tmp_path / "pose.sslt").write_text(f"topic pose:{POSE} contains X(me) = msg.pose.position.x\n")
    ttl = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    for n in (1, 2):
        (tmp_path / f"robot{n}.toml").write_text(
            f'[platforms.robot{n}]\nontology = "{ttl}"\nspecs = "pose.sslt"\n'
            f'namespace = "/robot{n}"\n'
        )
    return tmp_path


class Live:
    """A monitor on one session and publishers on another, joined on a free loopback port;
    the monitor runs in a thread, its events collected as they come."""

    def __init__(
        self,
        km: KnowledgeManager,
        formulas: list[str],
        *,
        store: Any = None,
        policy: StreamPolicy | None = None,
        until: Fraction | None = None,
        wait: float = 60.0,
        **options: Any,
    ) -> None:
        port = free_port()
        self.publishing = open_session([], [f"tcp/127.0.0.1:{port}"])
        self.watching = open_session([f"tcp/127.0.0.1:{port}"], [])
        self.monitor = Ros2Monitor(
            km,
            list(formulas),
            policy or StreamPolicy(max_age=Fraction(1)),
            self.watching,
            store=store or load_typestore({}, False, "ros2_jazzy"),
            **options,
        )
        self.events: list[Any] = []
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, args=(until, wait), daemon=True)
        self.thread.start()

    def _run(self, until: Fraction | None, wait: float) -> None:
        try:
            for event in self.monitor.run(until=until, duration=60, wait=wait):
                self.events.append(event)
        except BaseException as exc:
            self.error = exc

    def changes(self, kind: str) -> list[Change]:
        return [e for e in self.events if isinstance(e, Change) and e.event == kind]

    def verdicts(self) -> list[Verdict]:
        return [e for e in self.events if isinstance(e, Verdict)]

    def until(self, holds: Callable[[], bool], what: str, timeout: float = 30.0) -> None:
        """Wait for `holds` (a bound on failure, not a timing assumption)."""
        end = time.monotonic() + timeout
        while not holds():
            assert self.error is None, self.error
            assert time.monotonic() < end, f"not within {timeout} s: {what}"
            time.sleep(0.01)

    def matched(self, *pubs: Any) -> None:
        """Until the monitor's subscriptions have reached these publishers (a put before
        that goes nowhere)."""
        self.until(
            lambda: all(p.publisher.matching_status.matching for p in pubs),
            "the monitor's subscriptions reach the publishers",
        )

    def finish(self) -> None:
        self.monitor.stop.set()
        self.thread.join(30)
        assert not self.thread.is_alive()
        assert self.error is None, self.error

    def close(self) -> None:
        self.monitor.stop.set()
        self.thread.join(30)
        self.watching.close()
        self.publishing.close()


@pytest.fixture
def live() -> Iterator[Callable[..., Live]]:
    made: list[Live] = []

    def make(*args: Any, **kwargs: Any) -> Live:
        made.append(Live(*args, **kwargs))
        return made[-1]

    yield make
    for one in made:
        one.close()


def pose(store: Any, t: int, x: float) -> bytes:
    """A PoseStamped at `t` ns, at x."""
    types = store.types
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=t // S, nanosec=t % S), frame_id="map"
    )
    point = types["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0)
    quat = types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    msg = types[POSE](
        header=header, pose=types["geometry_msgs/msg/Pose"](position=point, orientation=quat)
    )
    return bytes(store.serialize_cdr(msg, POSE))


STORE = load_typestore({}, False, "ros2_jazzy")


def test_the_ros2_replay_gives_the_offline_verdicts_and_its_record_replays_them(
    traffic: Path, live: Callable[..., Live], tmp_path: Path
) -> None:
    """Three robots replay the traffic example as ROS 2 topics (rmw_zenoh's format, /clock);
    the monitor binds them by name, decodes CDR with --msg types, and decides what the
    recording decides offline; its --record file, replayed offline, decides the same."""
    config = REPO / "examples" / "federation.toml"
    store = load_typestore(msg_types(TRAFFIC_MSGS), False, "ros2_jazzy")
    policy = StreamPolicy(delay_before_approximation=Fraction(1, 2))
    km = KnowledgeManager.from_config(config)
    formulas = [SPEEDING, POSITION]
    offline = list(
        Monitor(km.plan(formulas), km.request, policy).run(RosbagSource(traffic, TRAFFIC_MSGS))
    )
    record = tmp_path / "run.mcap"
    run = live(
        km,
        formulas,
        store=store,
        policy=policy,
        sim_time=True,
        recorder=Recorder(record, store),
        until=Fraction(400),
    )
    sent = replay(traffic, run.publishing, speed=200, wait_for=TRAFFIC_TOPICS)
    assert sent > 2900
    run.until(
        lambda: run.monitor.clock is not None and run.monitor.clock >= 359 * S,
        "the monitor's clock reaches the recording's end",
    )
    run.finish()
    assert {c.topic for c in run.changes("subscribed")} == {
        t.rsplit("/", 1)[1] for t in TRAFFIC_TOPICS[1:]
    }
    assert run.verdicts() == [v for v in offline if isinstance(v, Verdict)]
    assert run.verdicts()[0].verdict is False and run.verdicts()[0].time == 300.02
    replayed = list(Monitor(km.plan(formulas), km.request, policy).run(RosbagSource(record)))
    assert [v for v in replayed if isinstance(v, Verdict)] == run.verdicts()
    again = open_session([], [f"tcp/127.0.0.1:{free_port()}"])
    try:  # the record's JSON channel is no ROS 2 topic: replayed are its ROS messages only
        assert replay(record, again, speed=1e9, clock=False) == run.monitor.received
    finally:
        again.close()


def test_bridge_tokens_are_taken_with_bridge_and_named_otherwise(
    robots: Path, live: Callable[..., Live], caplog: pytest.LogCaptureFixture
) -> None:
    km = KnowledgeManager.from_config(robots / "robot1.toml")
    without = live(km, ["always (X[me] < 15)"], sim_time=True)
    bridged = Ros2Node(without.publishing, "turtle", "/robot1", bridged=True)
    bridged.publisher("/robot1/pose", POSE)  # the node holds it: a dropped one is undeclared
    without.until(lambda: "give --bridge" in caplog.text, "the bridge's topic named")
    assert not without.monitor.subs
    run = live(km, ["always (X[me] < 15)"], bridge=True)
    pub = Ros2Node(run.publishing, "turtle", "/robot1", bridged=True).publisher(
        "/robot1/pose", POSE
    )
    run.until(lambda: bool(run.changes("subscribed")), "subscribed through the bridge")
    run.matched(pub)
    assert "through the bridge" in run.changes("subscribed")[0].detail
    assert pub.key == "robot1/pose"  # the bridge's key: the topic, no type, no attachment
    pub.put(pose(STORE, 7 * S, 20.0))
    run.until(lambda: run.monitor.received == 1, "the bridged sample taken")
    run.until(lambda: bool(run.verdicts()), "its verdict")
    assert (run.verdicts()[0].verdict, run.verdicts()[0].time) == (False, 7)


def test_a_late_publisher_is_subscribed_and_a_vanished_one_is_source_loss(
    robots: Path, live: Callable[..., Live]
) -> None:
    km = KnowledgeManager.from_config(robots / "robot1.toml")
    run = live(km, ["always (X[me] < 15)"], sim_time=True, keep_states=True)
    player = Ros2Node(run.publishing, "player").publisher("/clock", "rosgraph_msgs/msg/Clock")
    run.until(lambda: "0/clock" in "".join(run.monitor.subs), "the clock subscribed")
    run.matched(player)
    player.put(cdr_clock(1 * S))
    run.until(lambda: run.monitor.clock == 1 * S, "the first tick")
    assert not run.changes("subscribed")  # nobody publishes the pose yet
    pub = Ros2Node(run.publishing, "turtle", "/robot1").publisher("/robot1/pose", POSE)
    run.until(lambda: bool(run.changes("subscribed")), "the late publisher subscribed")
    run.matched(pub)
    for n in range(2, 5):
        player.put(cdr_clock(n * S))
        pub.put(pose(STORE, n * S, 1.0 + n))
    run.until(lambda: run.monitor.received == 3, "three poses taken")
    pub.close()
    run.until(lambda: bool(run.changes("source_lost")), "source loss reported")
    lost = run.changes("source_lost")[0]
    assert lost.feature == "X[me]" and lost.last_sample == 4  # s, like every event time
    assert run.changes("unsubscribed")[0].topic == "pose"
    player.put(cdr_clock(7 * S))  # past the maximum age (1 s) of the last pose
    run.until(
        lambda: any(s.get(k) is None for _, s in run.monitor.monitor.states for k in s),
        "X[me] turned unknown",
    )
    unknown = next(t for t, s in run.monitor.monitor.states if None in s.values())
    assert unknown == 5 * S + 1  # the instant the last pose (4 s) is older than 1 s
    run.finish()


def test_a_type_the_typestore_does_not_know_is_one_warning_and_skipped(
    tmp_path: Path, live: Callable[..., Live], caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "t.sslt").write_text("topic /turtle1/pose:turtlesim/Pose contains X(me) = msg.x\n")
    ttl = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    (tmp_path / "t.toml").write_text(f'[platforms.t]\nontology = "{ttl}"\nspecs = "t.sslt"\n')
    run = live(KnowledgeManager.from_config(tmp_path / "t.toml"), ["always (X[me] < 15)"])
    node = Ros2Node(run.publishing, "turtlesim")
    node.publisher("/turtle1/pose", "turtlesim/msg/Pose")
    node.publisher("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")  # not wanted: no word
    run.until(lambda: "turtlesim/msg/Pose" in caplog.text, "the unknown type named")
    lines = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert lines == [
        "/turtle1/pose: type turtlesim/msg/Pose is not known (give its .msg "
        "file with --msg, or --typestore); skipped"
    ]
    assert not run.monitor.subs


def test_payloads_that_are_not_cdr_too_large_or_torn_are_counted_and_the_rest_kept(
    robots: Path,
    live: Callable[..., Live],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    monkeypatch.setattr("dkreason.live.ros2.MAX_PAYLOAD", 1000)
    km = KnowledgeManager.from_config(robots / "robot1.toml")
    run = live(km, ["always (X[me] < 15)"])
    pub = Ros2Node(run.publishing, "turtle", "/robot1", labelled=True).publisher(
        "/robot1/pose", POSE
    )  # a robot on Jazzy's first rmw_zenoh
    run.until(lambda: bool(run.changes("subscribed")), "subscribed")
    run.matched(pub)
    good = pose(STORE, time.time_ns(), 3.0)
    pub.put(b'{"x": 1}')  # JSON, not CDR
    pub.put(good)  # the first good one: decoded in full once, then read field by field
    pub.put(good[:22])  # torn before the field read (a cut after it still gives the field)
    pub.put(b"\x00\x01\x00\x00" + bytes(2000))  # over the bound
    pub.put(b"\x00\x01\x00\x00\xff\xff\xff\x7f")  # a string length far past the end
    pub.put(pose(STORE, time.time_ns(), 4.0))
    run.until(lambda: run.monitor.received == 2, "both good poses taken")
    run.until(lambda: sum(run.monitor.rejected.values()) == 4, "the four bad ones counted")
    assert {kind for _, kind in run.monitor.rejected} == {"cdr", "decode", "size"}
    assert run.monitor.labelled  # so verdicts published back use its attachment layout
    assert "rejected /robot1/pose (cdr, 1 so far)" in caplog.text
    run.finish()


def test_ids_namespaces_and_bindings_are_those_of_recordings(
    robots: Path, live: Callable[..., Live], tmp_path: Path
) -> None:
    """robot1's relative `pose` is /robot1/pose (its namespace), never /robot2/pose; for
    platforms without a namespace, --bind names the node namespace that is each robot's."""
    run = live(KnowledgeManager.from_config(robots / "robot1.toml"), ["always (X[me] < 15)"])
    nodes = [Ros2Node(run.publishing, "turtle", f"/robot{n}") for n in (1, 2)]  # held: a
    for n, node in enumerate(nodes, 1):  # dropped node's publishers are undeclared
        node.publisher(f"/robot{n}/pose", POSE)
    run.until(lambda: len(run.monitor.seen) == 2, "both publishers seen")
    assert [s.topic for s in run.monitor.subs.values()] == ["/robot1/pose"]
    run.close()
    (tmp_path / "odom.sslt").write_text(
        f"topic /odom:{POSE} contains X(me) = msg.pose.position.x\n"
    )
    ttl = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    (tmp_path / "pair.toml").write_text(
        f'local = "robot2"\n[platforms.robot1]\nontology = "{ttl}"\nspecs = "odom.sslt"\n'
        f'[platforms.robot2]\nontology = "{ttl}"\nspecs = "odom.sslt"\n'
    )
    pair = live(
        KnowledgeManager.from_config(tmp_path / "pair.toml"),
        ["always (X[me] < 15)"],
        bind={"robot1": "/r1", "robot2": "/r2"},
    )
    nodes = [Ros2Node(pair.publishing, "turtle", f"/r{n}") for n in (1, 2)]
    for n, node in enumerate(nodes, 1):
        node.publisher(f"/r{n}/odom", POSE)
    pair.until(lambda: len(pair.changes("subscribed")) == 2, "both subscribed")
    assert {(c.platform, c.detail.split()[0]) for c in pair.changes("subscribed")} == {
        ("robot1", "/r1/odom"),
        ("robot2", "/r2/odom"),
    }  # one vocabulary: both feed X[me]


def test_a_malformed_token_and_a_flood_keep_the_monitor_running_and_lose_nothing(
    robots: Path, live: Callable[..., Live]
) -> None:
    run = live(KnowledgeManager.from_config(robots / "robot1.toml"), ["always (X[me] < 15)"])
    bad = run.publishing.liveliness().declare_token(
        "@ros2_lv/0/aa/0/10/MP/%/%/n/%robot1%pose/geometry_msgs::PoseStamped/h/q"
    )
    pub = Ros2Node(run.publishing, "turtle", "/robot1").publisher("/robot1/pose", POSE)
    run.until(lambda: bool(run.changes("subscribed")), "subscribed")
    run.matched(pub)
    assert run.monitor.rejected == {("tokens", "token"): 1}
    message = pose(STORE, time.time_ns(), 1.0)
    for _ in range(20_000):
        pub.put(message)
    run.until(lambda: run.monitor.received == 20_000, "every sample of the flood taken", 120)
    run.finish()
    bad.undeclare()


def test_verdicts_go_back_onto_the_network_as_json_and_as_a_ros2_topic(
    live: Callable[..., Live], robots: Path
) -> None:
    port = free_port()
    talker = open_session([], [f"tcp/127.0.0.1:{port}"])
    listener = open_session([f"tcp/127.0.0.1:{port}"], [])
    got: list[tuple[str, bytes]] = []
    attachments: list[bytes] = []
    subs = [
        listener.declare_subscriber(
            key, lambda s: got.append((str(s.key_expr), s.payload.to_bytes()))
        )
        for key in (
            "dkreason/verdicts/**",
            rmw.data_key("/dkreason/verdicts", "std_msgs/msg/String"),
        )
    ]
    subs.append(
        listener.declare_subscriber(
            rmw.data_key("/dkreason/verdicts", "std_msgs/msg/String"),
            lambda s: attachments.append(s.attachment.to_bytes()),
        )
    )
    labelled = [False]  # what the monitor has seen of the robots' attachments
    tokens: list[str] = []
    lv = listener.liveliness().declare_subscriber(
        f"{rmw.ADMIN}/**", lambda s: tokens.append(str(s.key_expr))
    )
    try:
        announce = Announcer(
            talker, ["always (X[me] < 15)"], ros2=True, labelled=lambda: labelled[0]
        )
        deadline = time.monotonic() + 30
        while not tokens and time.monotonic() < deadline:
            time.sleep(0.01)
        verdict = Verdict("always (X[me] < 15)", False, 2, False, "X[me] < 15 failed at 2")
        for _ in range(100):  # until the subscriptions reach the talker
            announce(verdict)
            if len({k for k, _ in got}) == 2 and attachments:
                break
            time.sleep(0.05)
        labelled[0] = True  # robots on Jazzy's first rmw_zenoh: theirs is what they read
        announce(verdict)
        deadline = time.monotonic() + 30
        while len(attachments[-1]) != 77 and time.monotonic() < deadline:
            time.sleep(0.01)
        announce.close()
    finally:
        for s in (*subs, lv):
            s.undeclare()
        talker.close()
        listener.close()
    pub = rmw.parse_token(tokens[0])
    assert pub is not None and (pub.topic, pub.msgtype) == (
        "/dkreason/verdicts",
        "std_msgs/msg/String",
    )
    as_json = json.loads(next(p for k, p in got if k == "dkreason/verdicts/f1"))
    assert as_json["id"] == "f1" and as_json["verdict"] is False and as_json["time"] == 2
    assert len(attachments[0]) == 33 and rmw.parse_attachment(attachments[-1])[0] > 1
    ros = next(p for k, p in got if k.startswith("0/"))
    length = struct.unpack_from("<I", ros, 4)[0]
    as_ros = json.loads(ros[8 : 8 + length - 1])
    assert as_ros.pop("ids") == [as_json.pop("id")] and as_ros == as_json


def test_a_violation_goes_to_every_formula_that_reads_its_feature() -> None:
    """Each formula's key carries what concerns it: its verdict, and the stream constraint
    violations and re-routes of the features it reads."""
    from dkreason.model import FeatureKey
    from dkreason.monitor import Rerouted
    from dkreason.stream.processor import Violation

    class Session:
        def __init__(self) -> None:
            self.puts: list[tuple[str, Any]] = []

        def put(self, key: str, payload: bytes) -> None:
            self.puts.append((key, json.loads(payload)))

    speed, position = FeatureKey("Speed", ("car2",)), FeatureKey("Position", ("car2",))
    formulas = {SPEEDING: [speed], POSITION: [position], "always (Speed[car2] < 200)": [speed]}
    session = Session()
    announce = Announcer(
        session,
        list(formulas),
        reads=lambda key: [text for text, keys in formulas.items() if key in keys],
    )
    announce(Violation("late", 5 * S, speed, "platform1/topic4", "a late sample"))
    announce(Violation("late", 6 * S, FeatureKey("Altitude", ("uav1",)), "t", "unread"))
    assert [(k, p["id"], p["violation"]) for k, p in session.puts] == [
        ("dkreason/verdicts/f1", "f1", "late"),
        ("dkreason/verdicts/f3", "f3", "late"),
        ("dkreason/verdicts/violations", "violations", "late"),
    ]
    session.puts.clear()
    aside = Rerouted(7, speed, "platform1/topic4", True, ("platform1/topic4",), (), "silent")
    announce(aside)  # a source set aside: to the formulas reading the feature it fed
    assert [(k, p["rerouted"], p["change"], p["after"]) for k, p in session.puts] == [
        ("dkreason/verdicts/f1", "Speed[car2]", "set_aside", []),
        ("dkreason/verdicts/f3", "Speed[car2]", "set_aside", []),
    ]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--bridge"], "--bridge is for --ros2"),
        (["--ros2", "--bind", "robot1"], "expected PLATFORM=/NAMESPACE"),
        (["--ros2", "--bind", "nobody=/x"], "not a platform of the config"),
        (["--ros2", "--source", "x.mcap"], "--ros2 takes no --source"),
        (["--ros2", "--foxglove", "robot:"], "--foxglove 'robot:': expected [HOST:]PORT"),
        (["--ros2", "--speed", "2"], "--speed is for recordings"),
        (
            ["--publish-verdicts", "--source", "x.mcap"],
            "--publish-verdicts is for --live or --ros2",
        ),
    ],
)
def test_ros2_options_misused_are_one_line_and_exit_2(
    argv: list[str], message: str, robots: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        main(["monitor", "--config", str(robots / "robot1.toml"), *argv, "always (X[me] < 15)"])
        == 2
    )
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_the_cli_monitors_ros2_robots_records_and_publishes_its_verdicts(
    traffic: Path, tmp_path: Path
) -> None:
    """`dkreason monitor --ros2 --sim-time --json --record --publish-verdicts --foxglove`
    against the replayed robots: the offline verdicts, as JSON lines; the record replays
    them; the verdicts arrive on dkreason/verdicts/f1; Foxglove is served meanwhile."""
    import subprocess
    import sys

    port = free_port()
    session = open_session([], [f"tcp/127.0.0.1:{port}"])
    got: list[bytes] = []
    listener = session.declare_subscriber(
        "dkreason/verdicts/f1", lambda s: got.append(s.payload.to_bytes())
    )
    record = tmp_path / "run.mcap"
    args = [
        "monitor",
        "--config",
        str(REPO / "examples" / "federation.toml"),
        "--delay",
        "0.5",
        *(a for m in TRAFFIC_MSGS for a in ("--msg", str(m))),
        SPEEDING,
    ]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dkreason.cli",
            *args,
            "--ros2",
            "--sim-time",
            "--json",
            "--record",
            str(record),
            "--publish-verdicts",
            "--foxglove",
            "127.0.0.1:0",
            "--connect",
            f"tcp/127.0.0.1:{port}",
            "--until",
            "330",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        replay(traffic, session, speed=200, wait_for=TRAFFIC_TOPICS[:-1], timeout=60)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        listener.undeclare()
        session.close()
    assert proc.returncode == 1, err
    assert "serving Foxglove on ws://localhost:" in err
    lines = [json.loads(line) for line in out.splitlines()]
    verdicts = [(v["verdict"], v["time"]) for v in lines if "verdict" in v and "update" not in v]
    assert verdicts == [(False, 300.02)]
    assert {c["topic"] for c in lines if c.get("event") == "subscribed"} >= {"topic4"}
    assert json.loads(got[0])["verdict"] is False
    offline = subprocess.run(
        [sys.executable, "-m", "dkreason.cli", *args, "--json", "--source", str(record)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert [
        (v["verdict"], v["time"])
        for v in map(json.loads, offline.stdout.splitlines())
        if "verdict" in v and "update" not in v
    ] == verdicts


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_record_that_cannot_be_written_is_one_error_and_stops_the_run() -> None:
    """A full disk is the monitor's own trouble, not a peer's: one line naming the file."""
    import os

    from dkreason.live.record import RecordError

    recorder = Recorder(Path("/dev/full"), STORE, force=True)
    with pytest.raises(RecordError, match=r"^--record /dev/full: No space left on device"):
        for n in range(10_000):  # incompressible: the writer's chunks reach the file
            recorder.message("/robot1/pose", POSE, n, n, os.urandom(1000))
        recorder.close()
    recorder.close()  # once failed, closing again is quiet


def test_record_refuses_an_existing_file_unless_forced(
    robots: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 27, defect 7: `--record` overwrote an existing file without a word."""
    from dkreason.errors import DkError

    kept = tmp_path / "yesterday.mcap"
    kept.write_bytes(b"a run worth keeping")
    argv = ["monitor", "--ros2", "--config", str(robots / "robot1.toml"), "--record", str(kept)]
    assert main([*argv, "always (X[me] < 15)"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists" in err and "--force" in err
    with pytest.raises(DkError, match="exists"):
        Recorder(kept, STORE)
    assert kept.read_bytes() == b"a run worth keeping"
    Recorder(kept, STORE, force=True).close()
    assert kept.read_bytes().startswith(b"\x89MCAP")  # overwritten, as asked


FLEET_TTL = """@prefix : <http://turtles.org/o#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
:Robot a owl:Class .
:UnaryRelation a owl:Class .
:arg1 a owl:ObjectProperty .
:X a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (
    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; owl:allValuesFrom :Robot ] ) ] .
:r1 a owl:NamedIndividual, :Robot .
:r2 a owl:NamedIndividual, :Robot .
"""


@pytest.fixture
def pair(tmp_path: Path) -> KnowledgeManager:
    """One config, two robots' poses: X[r1] from /robot1/pose, X[r2] from /robot2/pose."""
    (tmp_path / "pair.ttl").write_text(FLEET_TTL)
    (tmp_path / "pair.sslt").write_text(
        "".join(
            f"topic /robot{n}/pose:{POSE} contains X(r{n}) = msg.pose.position.x\n" for n in (1, 2)
        )
    )
    (tmp_path / "pair.toml").write_text(
        '[platforms.fleet]\nontology = "pair.ttl"\nspecs = "pair.sslt"\n'
    )
    return KnowledgeManager.from_config(tmp_path / "pair.toml")


class SimRobots:
    """A /clock player and the two robots of `pair` on a Live monitor, on sim time."""

    def __init__(self, run: Live) -> None:
        self.run = run
        self.player = Ros2Node(run.publishing, "player").publisher(
            "/clock", "rosgraph_msgs/msg/Clock"
        )
        self.robots = [
            Ros2Node(run.publishing, "turtle", f"/robot{n}").publisher(f"/robot{n}/pose", POSE)
            for n in (1, 2)
        ]
        run.until(lambda: len(run.changes("subscribed")) == 2, "both robots subscribed")
        run.until(lambda: any(s.topic == "/clock" for s in run.monitor.subs.values()), "/clock")
        run.matched(self.player, *self.robots)

    def second(self, t: float, clock: Any = None, **poses: float) -> None:
        """A tick at t s (on `clock`, default the player), then each robot's pose stamped t."""
        (clock or self.player).put(cdr_clock(int(t * S)))
        for n, robot in enumerate(self.robots, 1):
            if f"r{n}" in poses:
                robot.put(pose(STORE, int(t * S), poses[f"r{n}"]))


def test_a_sample_stamped_far_ahead_is_early_for_its_own_topic_only(
    pair: KnowledgeManager, live: Callable[..., Live]
) -> None:
    """One pose of robot 2 stamped 60 s ahead of the clock made the data seem to run 60 s
    longer, so robot 1's formula ended unknown ("silent for 57 s"): now that pose is an
    `early` violation of X[r2] alone, and not taken."""
    formulas = ["always (X[r1] < 15)", "always (X[r2] < 15)"]
    run = live(pair, formulas, sim_time=True)
    sim = SimRobots(run)
    for n in range(1, 6):
        sim.second(n, r1=1.0, r2=2.0)
        if n == 2:
            sim.robots[1].put(pose(STORE, 62 * S, 3.0))
    run.until(lambda: run.monitor.received >= 10, "the poses taken")
    run.finish()
    assert [(v.formula, v.verdict) for v in run.verdicts()] == [
        (formulas[0], True),
        (formulas[1], True),
    ]
    violations = [e for e in run.events if isinstance(e, Violation)]
    assert [(v.constraint, str(v.feature), v.time) for v in violations] == [("early", "X[r2]", 2)]
    assert "valid at 62 s" in violations[0].detail


def _sim_run(
    pair: KnowledgeManager, live: Callable[..., Live], disturb: str
) -> tuple[Live, list[Verdict]]:
    """Robot 1 at x = 1 for 5 s, then 20 (a violation at 6 s), robot 2 at 2, on sim time:
    `control` on a steady clock; `reset` with the simulator restarted after 4 s (its clock
    back to 0); `stranger` with another node ticking /clock at 2^31 - 1 s after 3 s."""
    formulas = ["always (X[r1] < 15)", "always (X[r2] < 15)"]
    run = live(pair, formulas, sim_time=True)
    sim = SimRobots(run)
    timeline: list[tuple[int, int | None]] = [(n, n) for n in range(1, 7)]
    if disturb == "reset":
        timeline = [(1, 1), (2, 2), (3, 3), (4, 4), (0, None), (1, 5), (2, 6)]
    rogue = Ros2Node(run.publishing, "rogue").publisher("/clock", CLOCK_TYPE)
    run.until(lambda: len(run.monitor.subs[rogue.key].publishers) == 2, "both /clock seen")
    for clock, second in timeline:
        if second is None:
            sim.second(clock)
        else:
            sim.second(clock, r1=20.0 if second == 6 else 1.0, r2=2.0)
        if disturb == "stranger" and second == 3:
            rogue.put(cdr_clock((2**31 - 1) * S))
    run.until(lambda: run.monitor.received == 12, "every pose taken")
    run.finish()
    return run, run.verdicts()


@pytest.mark.parametrize("disturb", ["reset", "stranger"])
def test_a_clock_reset_or_a_strangers_tick_keeps_the_control_runs_verdicts(
    pair: KnowledgeManager,
    live: Callable[..., Live],
    caplog: pytest.LogCaptureFixture,
    disturb: str,
) -> None:
    """The sim clock only moved forward: a simulator reset (or a restarted `ros2 bag play`),
    or one tick at 2^31 - 1 s from any node, made every formula unknown with a flood of
    `late` events and missed the violation.  Now a backward jump is a reset (one event; the
    stream goes on from where it was) and only the first /clock publisher is followed (the
    others' ticks said in one line): the verdicts are the control run's, nothing is late."""
    _, control = _sim_run(pair, live, "control")
    assert [(v.verdict, v.time) for v in control] == [(False, 6), (True, 6)]
    run, verdicts = _sim_run(pair, live, disturb)
    assert verdicts == control
    assert not [e for e in run.events if isinstance(e, Violation)]
    resets = run.changes("clock_reset")
    if disturb == "reset":
        (reset,) = resets
        assert str(reset) == (
            "at 4 s: /clock reset (it went back from 4 s to 0 s; the stream goes on from 4 s)"
        )
    else:
        assert not resets
        assert "/clock: ticks from more than one publisher: only the first" in caplog.text


class _Quiet:
    """A session that declares nothing: a Ros2Monitor's events handed to it directly."""

    def liveliness(self) -> _Quiet:
        return self

    def declare_subscriber(self, *_: Any, **__: Any) -> _Quiet:
        return self

    def undeclare(self) -> None:
        pass


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 2**40), st.booleans()),  # (tick in ns, from a stranger)
        max_size=30,
    )
)
def test_whatever_clock_publishers_put_the_stream_clock_never_goes_back(
    ticks: list[tuple[int, bool]],
) -> None:
    """Each backward tick of the publisher followed is one reset; a stranger's tick never
    moves the clock."""
    monitor = Ros2Monitor(_turtle(), ["true"], StreamPolicy(), _Quiet(), store=STORE, sim_time=True)
    token = rmw.publisher_token("aa", 1, 10, "/", "player", "/clock", CLOCK_TYPE)
    key = rmw.data_key("/clock", CLOCK_TYPE)
    assert monitor.handle(("token", token, True)) == []
    clocks: list[int | None] = [None]
    resets = 0
    for t, stranger in ticks:
        attachment = rmw.attachment(1, 0, (b"s" if stranger else b"p") * 16)
        events = monitor.handle(("sample", key, cdr_clock(t), attachment, 0))
        resets += sum(isinstance(e, Change) and e.event == "clock_reset" for e in events)
        clocks.append(monitor.now())
        if stranger != ticks[0][1]:  # the first publisher heard is the one followed
            assert clocks[-1] == clocks[-2]
    followed = [t for t, stranger in ticks if stranger == ticks[0][1]]
    assert resets == sum(b < a for a, b in itertools.pairwise(followed))
    assert all(b is not None and (a is None or a <= b) for a, b in itertools.pairwise(clocks))


@functools.cache
def _turtle() -> KnowledgeManager:
    return KnowledgeManager.from_config(REPO / "tests" / "data" / "turtles" / "robot1.toml")


def test_a_publisher_whose_type_hash_is_not_the_definitions_is_one_warning_and_skipped(
    tmp_path: Path, live: Callable[..., Live], caplog: pytest.LogCaptureFixture
) -> None:
    """A CarMsg of another layout (its fields reordered) was read as if it were ours (speed 50
    read as 200.0): the hash in its token says so, and it is skipped unless --msg gives the
    definition with that hash."""
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    for folder, text in ((ours, "int32 id\nfloat64 spd\n"), (theirs, "float64 spd\nint32 id\n")):
        (folder / "dkreason_msgs" / "msg").mkdir(parents=True)
        (folder / "dkreason_msgs" / "msg" / "CarMsg.msg").write_text(text)
    stores = {
        f: load_typestore(msg_types([f / "dkreason_msgs/msg/CarMsg.msg"]), False, "ros2_jazzy")
        for f in (ours, theirs)
    }
    car = "dkreason_msgs/msg/CarMsg"
    (tmp_path / "car.sslt").write_text(f"topic car:{car} contains X(me) = msg.spd\n")
    ttl = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    (tmp_path / "car.toml").write_text(
        f'[platforms.robot1]\nontology = "{ttl}"\nspecs = "car.sslt"\nnamespace = "/robot1"\n'
    )
    km = KnowledgeManager.from_config(tmp_path / "car.toml")
    their_hash = stores[theirs].hash_rihs01(car)
    assert their_hash != stores[ours].hash_rihs01(car)

    def watch(store: Any) -> Live:
        run = live(km, ["always (X[me] < 100)"], store=store)
        Ros2Node(run.publishing, "car", "/robot1").publisher("/robot1/car", car, their_hash)
        return run

    refused = watch(stores[ours])
    refused.until(lambda: "type hash" in caplog.text, "the warning")
    assert not refused.monitor.subs
    refused.close()
    taken = watch(stores[theirs])  # --msg gives their definition
    taken.until(lambda: bool(taken.changes("subscribed")), "subscribed")
    (line,) = [r.getMessage() for r in caplog.records if "type hash" in r.getMessage()]
    assert line.startswith(f"/robot1/car ({car}) by /robot1/car: type hash {their_hash[:14]}")
    assert line.endswith("skipped (give --msg with the definition it was built from)")


def test_an_unset_stamp_is_no_stamp_and_features_nobody_feeds_are_named(
    robots: Path, live: Callable[..., Live], caplog: pytest.LogCaptureFixture
) -> None:
    """A header stamp of zero (never set, as many drivers leave it) is not 1970: the source
    time is taken.  A feature no publisher feeds after `wait` is named with the names it binds
    by and the publishers seen instead: names that do not bind are the usual day-one trouble."""
    km = KnowledgeManager.from_config(robots / "robot1.toml")
    clockless = live(km, ["always (X[me] < 15)"], wait=0.1, sim_time=True)
    clockless.until(lambda: "no /clock yet" in caplog.text, "the missing clock named")
    run = live(km, ["always (X[me] < 15)"])
    node = Ros2Node(run.publishing, "turtle", "/robot2")
    node.publisher("/robot2/pose", POSE)
    run.until(lambda: len(run.monitor.seen) == 1, "the publisher seen")
    caplog.clear()
    run.monitor.unfed()  # what `wait` s after the start says
    assert caplog.messages == [
        "no publisher yet for X[me] (it binds by /robot1/pose); publishers seen: /robot2/pose"
    ]
    before = time.time_ns()
    pub = Ros2Node(run.publishing, "turtle", "/robot1").publisher("/robot1/pose", POSE)
    run.until(lambda: bool(run.changes("subscribed")), "subscribed")
    run.matched(pub)
    pub.put(pose(STORE, 0, 20.0))
    run.until(lambda: bool(run.verdicts()), "the verdict")
    verdict = run.verdicts()[0]
    assert verdict.verdict is False and verdict.time >= before / S


SDK_PUBLISHER = """
import sys, time
from zenoh_ros2_sdk import ROS2Publisher
pub = ROS2Publisher(topic="/robot1/value", msg_type="std_msgs/msg/Float64",
                    msg_definition="float64 data\\n", namespace="/robot1", node_name="sdk",
                    router_port=int(sys.argv[1]))
for i in range(600):  # until the test has what it needs and stops it (30 s at most)
    pub.publish(data=float(i))
    time.sleep(0.05)
"""
SDK_SUBSCRIBER = """
import os, sys, time
from zenoh_ros2_sdk import ROS2Subscriber
got = []
sub = ROS2Subscriber(topic="/dkreason/verdicts", msg_type="std_msgs/msg/String",
                     msg_definition="string data\\n", callback=got.append,
                     router_port=int(sys.argv[1]))
end = time.time() + 30
while not got and time.time() < end:
    time.sleep(0.05)
print(got[0].data if got else "", flush=True)
os._exit(0)  # the SDK's session threads would hold the interpreter
"""


def test_an_independent_rmw_zenoh_implementation_talks_with_dkreason_both_ways(
    robots: Path, tmp_path: Path
) -> None:
    """zenoh-ros2-sdk (its own tokens, keys, RIHS01 hashes and attachments) publishes a
    std_msgs/msg/Float64 the monitor discovers, binds and judges; and it receives the verdicts
    dkreason publishes as /dkreason/verdicts."""
    import subprocess
    import sys

    pytest.importorskip("zenoh_ros2_sdk")
    (tmp_path / "v.sslt").write_text("topic value:std_msgs/msg/Float64 contains X(me) = msg.data\n")
    ttl = REPO / "tests" / "data" / "turtles" / "turtle.ttl"
    (tmp_path / "v.toml").write_text(
        f'[platforms.robot1]\nontology = "{ttl}"\nspecs = "v.sslt"\nnamespace = "/robot1"\n'
    )
    log = tmp_path / "sdk.log"  # a file, not a pipe: the SDK logs freely and never blocks
    port = free_port()
    session = open_session([], [f"tcp/127.0.0.1:{port}"])  # the SDK connects to it
    monitor = Ros2Monitor(
        KnowledgeManager.from_config(tmp_path / "v.toml"),
        ["always (X[me] < 15)"],
        StreamPolicy(),
        session,
        store=STORE,
    )
    with log.open("w") as sink:
        sdk = subprocess.Popen(
            [sys.executable, "-c", SDK_PUBLISHER, str(port)], stdout=sink, stderr=sink
        )
    try:
        events = list(monitor.run(duration=60))
    finally:
        sdk.kill()
        sdk.wait()
        session.close()
    verdicts = [e for e in events if isinstance(e, Verdict)]
    assert [v.verdict for v in verdicts] == [False], log.read_text()[-2000:]
    assert "X[me] = 15.0" in str(verdicts[0].witness)
    subscribed = [e for e in events if isinstance(e, Change) and e.event == "subscribed"]
    assert "/robot1/value (std_msgs/msg/Float64) by /robot1/sdk" in subscribed[0].detail

    port = free_port()
    session = open_session([], [f"tcp/127.0.0.1:{port}"])
    announce = Announcer(session, ["always (X[me] < 15)"], ros2=True)
    out = tmp_path / "sdk.out"
    with out.open("w") as answer, log.open("w") as sink:
        sdk = subprocess.Popen(
            [sys.executable, "-c", SDK_SUBSCRIBER, str(port)], stdout=answer, stderr=sink
        )
    try:
        deadline = time.monotonic() + 60
        while not out.read_text() and time.monotonic() < deadline:  # until it has one
            announce(verdicts[0])
            time.sleep(0.05)
    finally:
        sdk.kill()
        sdk.wait()
        announce.close()
        session.close()
    assert json.loads(out.read_text())["verdict"] is False, log.read_text()[-2000:]


def test_a_ros2_monitor_makes_no_attribute_while_running(robots: Path) -> None:
    session = open_session([], [f"tcp/127.0.0.1:{free_port()}"])
    try:
        monitor = Ros2Monitor(
            KnowledgeManager.from_config(robots / "robot1.toml"),
            ["always (X[me] < 15)"],
            StreamPolicy(),
            session,
            store=STORE,
        )
        before = set(vars(monitor))
        monitor.stop.set()
        (verdict,) = list(monitor.run())
    finally:
        session.close()
    assert isinstance(verdict, Verdict) and verdict.verdict is None
    assert set(vars(monitor)) == before


def test_a_monitor_that_falls_behind_holds_the_link_back_then_drops_and_says_so(
    robots: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Memory stays bounded on a flood the monitor cannot take: with its queue full, zenoh's
    thread waits (holding the link, and a blocking publisher, back); past that wait a sample
    is dropped and counted, and the count is logged."""
    monkeypatch.setattr("dkreason.live.ros2.QUEUED", 5)
    monkeypatch.setattr("dkreason.live.ros2.PUT_WAIT", 0.01)
    port = free_port()
    publishing = open_session([], [f"tcp/127.0.0.1:{port}"])
    watching = open_session([f"tcp/127.0.0.1:{port}"], [])
    try:
        monitor = Ros2Monitor(
            KnowledgeManager.from_config(robots / "robot1.toml"),
            ["always (X[me] < 15)"],
            StreamPolicy(),
            watching,
            store=STORE,
        )
        pub = Ros2Node(publishing, "turtle", "/robot1").publisher("/robot1/pose", POSE)
        deadline = time.monotonic() + 30
        while not monitor.inbox.items and time.monotonic() < deadline:
            time.sleep(0.01)  # the publisher's token queues up: nobody takes it yet
        for event in monitor.inbox.drain(0):
            monitor.handle(event)  # what the loop does: the publisher is subscribed
        assert monitor.subs
        while not pub.publisher.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        for n in range(20):
            pub.put(pose(STORE, (n + 1) * S, 1.0))
        while monitor.dropped < 15 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert len(monitor.inbox.items) == 5 and monitor.dropped == 15
        list(monitor.run(duration=1))  # takes the five, reports the fifteen, ends
        assert monitor.received == 5
        assert "15 samples or announcements dropped so far" in caplog.text
    finally:
        watching.close()
        publishing.close()


def pose_pair(tmp_path: Path, *declared: str) -> KnowledgeManager:
    """X[r1] from two robots' poses, each topic declaring the quality given for it."""
    (tmp_path / "pair.ttl").write_text(FLEET_TTL)
    (tmp_path / "pair.sslt").write_text(
        "".join(
            f"topic /robot{n}/pose:{POSE} {said} contains X(r1) = msg.pose.position.x\n"
            for n, said in enumerate(declared, 1)
        )
    )
    (tmp_path / "pair.toml").write_text(
        '[platforms.fleet]\nontology = "pair.ttl"\nspecs = "pair.sslt"\n'
    )
    return KnowledgeManager.from_config(tmp_path / "pair.toml")


BOTH_POSES, POSE1, POSE2 = (
    ("fleet:/robot1/pose", "fleet:/robot2/pose"),
    ("fleet:/robot1/pose",),
    ("fleet:/robot2/pose",),
)


@pytest.mark.parametrize(
    ("best_source", "read"), [(False, BOTH_POSES), (True, POSE1)], ids=["merged", "best-source"]
)
def test_a_robots_topic_that_stops_is_set_aside_and_taken_back_on_ros2(
    tmp_path: Path, live: Callable[..., Live], best_source: bool, read: tuple[str, ...]
) -> None:
    """X[r1] from both robots' poses, each declared 1 Hz: robot 1's poses stop after 3 s
    while /clock goes on, so X[r1] is read from robot 2's alone until robot 1 sends again
    at 9 s (its topic stays subscribed).  With --best-source robot 1's alone is read at
    first, robot 2's subscribed beside it (ranked next; of its poses before the switch,
    which may come at 7 or 8 s as the loop takes its batches, the newest feeds X[r1] then:
    the maximum age bridges robot 1's silence before it)."""
    from dkreason.monitor import Rerouted

    km = pose_pair(tmp_path, "[rate 1 Hz]", "[rate 1 Hz]")
    policy = StreamPolicy(max_age=10, best_source=best_source)
    run = live(km, ["always (X[r1] < 15)"], sim_time=True, policy=policy)
    sim = SimRobots(run)

    def moves() -> list[Rerouted]:
        return [e for e in run.events if isinstance(e, Rerouted)]

    for n in range(1, 9):
        sim.second(n, r1=1.0, r2=2.0) if n <= 3 else sim.second(n, r2=2.0)
    run.until(lambda: len(moves()) == 1, "robot 1's pose set aside")
    sim.second(9, r1=1.0, r2=2.0)
    run.until(lambda: len(moves()) == 2, "robot 1's pose taken back")
    run.finish()
    assert [(m.aside, m.before, m.after) for m in moves()] == [
        (True, read, POSE2),
        (False, POSE2, read),
    ]
    assert 7 <= moves()[0].time <= 8 and moves()[1].time == 9  # (when the clock passed)
    standing = {c.topic: c.detail.startswith("standing by: ") for c in run.changes("subscribed")}
    assert standing == {"/robot1/pose": False, "/robot2/pose": best_source}
    assert [v.verdict for v in run.verdicts()] == [True]


def test_a_ros2_monitor_matches_with_its_max_delay(
    tmp_path: Path, live: Callable[..., Live]
) -> None:
    """With --max-delay 100ms, robot 2's pose (declaring a 200 ms delay) is not relevant: it
    is not subscribed though it publishes, announced before robot 1's."""
    km = pose_pair(tmp_path, "[delay 20ms]", "[delay 200ms]")
    run = live(km, ["always (X[r1] < 15)"], policy=StreamPolicy(max_delay=Fraction(1, 10)))
    assert not [name for name in run.monitor.wants if "robot2" in name]
    robots = [
        Ros2Node(run.publishing, "turtle", f"/robot{n}").publisher(f"/robot{n}/pose", POSE)
        for n in (2, 1)
    ]
    run.until(lambda: bool(run.changes("subscribed")), "robot 1's pose subscribed")
    run.matched(robots[1])
    assert [c.topic for c in run.changes("subscribed")] == ["/robot1/pose"]
    run.finish()


def test_a_ros2_monitor_says_once_that_every_topic_of_a_feature_is_excluded(
    tmp_path: Path, live: Callable[..., Live], caplog: pytest.LogCaptureFixture
) -> None:
    """With --max-delay 10ms neither pose is relevant: said in one line naming the topics and
    why, as the offline monitor says it, not left to read as missing data."""
    km = pose_pair(tmp_path, "[delay 20ms]", "[delay 200ms]")
    run = live(km, ["always (X[r1] < 15)"], policy=StreamPolicy(max_delay=Fraction(1, 100)))
    (said,) = [r.message for r in caplog.records if "excluded by the policy" in r.message]
    assert said.startswith("X[r1]: every topic of it is excluded by the policy: fleet:/robot1/pose")
    assert "--max-delay is 10ms" in said
    run.finish()


def test_a_best_pose_that_never_comes_is_set_aside_from_the_clocks_start_on_ros2(
    tmp_path: Path, live: Callable[..., Live]
) -> None:
    """Under --best-source X[r1] is read from robot 1's pose (declared 1 Hz), which robot 1
    never publishes; robot 2's, standing by, comes each second.  Robot 1's pose is set aside
    three periods after the first /clock tick (when the stream clock started), and robot
    2's newest pose feeds X[r1] at once: the formula is judged."""
    from dkreason.monitor import Rerouted

    km = pose_pair(tmp_path, "[rate 1 Hz]", "[rate 1 Hz]")
    policy = StreamPolicy(best_source=True)
    run = live(km, ["always (X[r1] < 15)"], sim_time=True, policy=policy)
    sim = SimRobots(run)

    def moves() -> list[Rerouted]:
        return [e for e in run.events if isinstance(e, Rerouted)]

    for n in range(1, 7):
        sim.second(n, r2=2.0)
    run.until(lambda: len(moves()) == 1, "robot 1's pose set aside")
    run.finish()
    (move,) = moves()
    assert (move.aside, move.before, move.after) == (True, POSE1, POSE2)
    assert move.reason.startswith("no sample since the start (")
    assert 4 < move.time <= 6  # (when the clock passed three periods after its first tick)
    assert [v.verdict for v in run.verdicts()] == [True]
