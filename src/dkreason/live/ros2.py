"""Monitor live ROS 2 robots over Zenoh: rmw_zenoh, or DDS robots through zenoh-bridge-ros2dds.

No ROS installation is needed: publishers are discovered from their liveliness tokens (rmw.py),
bound to spec topics by name as recordings are (stream/binding.py: namespaces, `PLATFORM=`
binding, here by a node's namespace, remaps), and only the relevant ones are subscribed.  CDR
payloads are read with rosbags' typestores (standard types built in; custom types from `--msg`
files), only the fields the request needs (stream/fastread.py).

Time.  A sample's valid time is its `header.stamp` when it has one (a zero stamp is none);
otherwise the publisher's source time from the attachment (wall clock), or the sim clock at
arrival (`sim_time`).  Its available time is its arrival: the wall clock, or with `sim_time` the
latest `/clock`.  A sample valid more than `EARLY_NS` past its available time is an `early`
violation of its own features and is not taken (one stamp 60 s ahead would otherwise move the
end of the data, and every other feature would end unknown); one valid long before it is late
for its own features (the stream processor's `late`).  States are made as that clock passes
(on the wall clock held back by each topic's lag, `held`; less the policy's delay), so a silent
publisher's value turns unknown once it is older than the maximum age.  The inbox from zenoh's
threads is bounded (`QUEUED`): a monitor that falls behind holds the link back, and past
`PUT_WAIT` drops and says so.

Change.  A publisher that appears later is subscribed when it appears; one whose token goes
away is unsubscribed, and a feature left with no publisher is reported as source loss.  A
publisher of a type the typestore does not know, or of a type or fields other than its
specification says, is one warning line and is skipped.  A payload that is not CDR, too large
or does not decode is counted and reported (at 1, 10, 100… of a kind), never fatal.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from ..errors import DkError, WireError
from ..manager import KnowledgeManager
from ..model import FeatureKey, TopicMatch, stream_name
from ..monitor import Monitor, Watch
from ..plan import Parsed
from ..stream import fields
from ..stream.binding import message_type_fits, recording_names
from ..stream.policy import StreamPolicy
from ..stream.typestore import ros_reader
from ..stream.units import NS, seconds
from . import loop, rmw
from .change import Event, change
from .inbox import Inbox
from .record import Recorder, RecordError
from .rmw import CLOCK, CLOCK_TYPE
from .session import direct

log = logging.getLogger("dkreason.ros2")
MAX_PAYLOAD = 16 * 1024 * 1024  # bytes of one message
HOLD_NS = NS  # how long a topic's newest sample may hold states back (wall clock)
EARLY_NS = NS  # a sample valid further past the stream clock is early (a clock set wrong)
QUEUED = 200_000  # events waiting for the monitor, at most (a sample's bytes and times each)
PUT_WAIT = 1.0  # s a zenoh thread waits for room before an event is dropped
_NO_EVENTS: list[Event] = []  # what a sample usually makes happen; read, never changed


def decode(read: Callable[[bytes], Any], payload: bytes, msgtype: str) -> Any:
    """What `read` makes of a peer's payload; however it fails (rosbags and struct raise
    several kinds on a torn or lying payload), a WireError."""
    try:
        return read(payload)
    except Exception as exc:
        raise WireError(
            f"does not decode as {msgtype} ({str(exc)[:120] or type(exc).__name__})", "decode"
        ) from None


def held(now: int, topics: Iterable[tuple[int, int, int]]) -> int:
    """The wall-clock watermark at `now`, from each topic's (latest arrival, newest valid
    time, lag: arrival less valid time of its latest sample).  A topic's next sample comes
    after its newest (a publisher's samples are in order) and, arriving now or later with
    about the same lag, is valid at now - lag or later: so a topic holds the watermark back
    to max(newest, now - lag).  A healthy link (lag of a millisecond) holds it by that much,
    whatever the topic's rate; a congested one by its backlog.  No topic holds it by more
    than `HOLD_NS` (a publisher whose clock runs behind), nor once silent for that long."""
    floor, mark = now - HOLD_NS, now
    for arrived, newest, lag in topics:
        if arrived >= floor:
            mark = min(mark, max(newest, now - min(lag, HOLD_NS)))
    return mark


@dataclass(slots=True)
class _Sub:
    """One subscribed key expression: a topic of one type, from one or more publishers."""

    name: str  # as bound: the spec topic's recording name
    topic: str  # its ROS name
    msgtype: str
    read: Any  # raw CDR → the wanted values (and the header stamp)
    stamped: bool
    features: list[FeatureKey]
    handle: Any = None
    publishers: set[str] = field(default_factory=set)
    checked: bool = False  # the first message was decoded in full against the definition
    newest: int = -1  # ns, the newest valid time taken from it
    arrived: int = -1  # ns, the wall clock at its latest sample
    last_valid: int = -1  # ns, the valid time of its latest sample


class Ros2Monitor:
    def __init__(
        self,
        km: KnowledgeManager,
        formulas: list[str | Parsed],
        policy: StreamPolicy,
        session: Any,
        *,
        store: Any,
        domain: int = 0,
        bridge: bool = False,
        bind: Mapping[str, str] | None = None,
        remap: Mapping[str, str] | None = None,
        sim_time: bool = False,
        recorder: Recorder | None = None,
        keep_states: bool = False,
        watch: Watch | None = None,
    ) -> None:
        """`store`: a rosbags typestore; `bind`: platform → ROS namespace whose nodes (or
        topics) are that platform's; `remap`: ROS topic name → the name it is bound by;
        `bridge`: take zenoh-bridge-ros2dds' publishers too; `watch`: told each state (a
        Foxglove viewer)."""
        self.session, self.store = session, store
        self.domain, self.bridge, self.sim_time = domain, bridge, sim_time
        self.bind = {p: ns.rstrip("/") or "/" for p, ns in (bind or {}).items()}
        self.remap = dict(remap or {})
        self.recorder = recorder
        self.monitor = Monitor(
            km.plan(formulas), km.matcher(policy), policy, keep_states=keep_states, watch=watch
        )
        self.processor = self.monitor.start(loop.LiveSource())
        for said in self.monitor.unsaid():
            log.warning("%s", said)
        request = self.monitor.request
        namespaces = dict(request.namespaces)
        # recording name → the features it feeds, or stands by for (--best-source: ranked
        # after the chosen topic, subscribed so that the features can be re-routed to it)
        self.wants: dict[str, list[tuple[FeatureKey, TopicMatch]]] = {}
        self.standby: set[tuple[str, FeatureKey]] = set()
        for f in request.features:
            for m in (*f.topics, *f.standby):
                for name in recording_names(
                    m, request.local, namespaces.get(m.platform), request.shared_names
                ):
                    self.wants.setdefault(name, []).append((f.feature.key, m))
                    if m in f.standby:
                        self.standby.add((name, f.feature.key))
        self.inbox = Inbox(QUEUED)
        self.dropped = 0  # samples the queue had no room for within PUT_WAIT (zenoh threads)
        self.told = 0  # of those, reported
        self.seen: dict[str, rmw.Publisher] = {}  # token → every publisher discovered
        self.taken: dict[str, str] = {}  # token → the key expression subscribed for it
        self.subs: dict[str, _Sub] = {}  # key expression → subscription
        # feature → its subscribed keys (standing by too: they feed it once re-routed)
        self.feeding: dict[FeatureKey, set[str]] = {}
        self.warned: set[tuple[str, ...]] = set()
        self.hashes: dict[str, str] = {}  # type → its definition's REP-2011 hash, here
        self.rejected: dict[tuple[str, str], int] = {}
        self.clock: int | None = None  # sim time: the latest /clock, shifted past resets
        self.last_tick: int | None = None  # the latest /clock as its publisher put it
        self.shift = 0  # ns added to /clock time: what its resets took back
        self.ticker: tuple[bytes | None, ...] = ()  # (gid,) of the /clock publisher followed
        self.foreign_ticks = 0  # ticks of other /clock publishers, not followed
        self.labelled = False  # the robots' attachments are in Jazzy's first layout
        self.received = 0
        self.report_at: float | None = None  # monotonic s: name the features nothing feeds
        self.stop = threading.Event()
        self.declared = [
            session.liveliness().declare_subscriber(
                rmw.TOKENS, direct(self._on_token), history=True
            )
        ]

    # ---- zenoh callbacks (other threads): only enqueue ----------------------------------

    def _on_token(self, sample: Any) -> None:
        import zenoh

        self._put(("token", str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

    def _on_sample(self, key: str, sample: Any) -> None:
        attachment = sample.attachment
        self._put(
            (
                "sample",
                key,
                sample.payload.to_bytes(),
                None if attachment is None else attachment.to_bytes(),
                time.time_ns(),
            )
        )

    def _put(self, event: tuple[Any, ...]) -> None:
        """Memory stays bounded: a full queue holds zenoh's thread back (and so the link and
        a blocking publisher) for up to PUT_WAIT s; only then is the event dropped, and
        counted."""
        if not self.inbox.put(event, timeout=PUT_WAIT):
            self.dropped += 1

    # ---- the loop ----------------------------------------------------------------------

    def now(self) -> int | None:
        """The stream clock: the latest /clock with sim time (None before it), else wall."""
        return self.clock if self.sim_time else time.time_ns()

    def watermark(self) -> int | None:
        """Up to when every sample has been taken.  With sim time, the clock.  On the wall
        clock, now, held back by each topic as far as its samples lag (`held`): a congested
        link delays states instead of making its samples late, a slow topic on a healthy link
        delays nobody, and a silent or skewed publisher holds nobody for long."""
        if self.sim_time:
            return self.clock
        return held(
            time.time_ns(),
            ((s.arrived, s.newest, s.arrived - s.last_valid) for s in self.subs.values()),
        )

    def run(
        self, until: Fraction | None = None, duration: float | None = None, wait: float = 10.0
    ) -> Iterator[Event]:
        """Events as they happen until every formula is decided, the stream clock passes
        `until` (s), `duration` (wall s) is over, or `stop` is set; then the end verdicts,
        each recorded when asked.  `wait` s after the start, each feature no publisher feeds
        yet is named, with the names it would bind by and the publishers seen instead."""
        self.report_at = time.monotonic() + wait
        end = None if until is None else int(until * NS)
        try:
            for event in loop.run(self.monitor, self.processor, self, end, duration):
                if self.recorder is not None:
                    self.recorder.event(self.now() or 0, event)
                yield event
        finally:
            if self.recorder is not None:
                self.recorder.close()

    # ---- what the loop asks (loop.Feed) ------------------------------------------------

    def over(self) -> bool:
        return False  # robots publish until they stop: no end is announced

    def tick(self) -> None:
        """The features nothing feeds yet, named once `wait` is over; the samples dropped
        since the last pass, counted."""
        if self.report_at is not None and time.monotonic() >= self.report_at:
            self.report_at = None
            self.unfed()
        if self.dropped != self.told:
            self.told = self.dropped
            log.warning(
                "%d samples or announcements dropped so far: the monitor "
                "fell more than %g s behind with %d queued",
                self.told,
                PUT_WAIT,
                QUEUED,
            )

    def unfed(self) -> None:
        """One line per feature that no publisher feeds yet: what would feed it, and what
        is on the network instead (the usual day-one trouble: names that do not bind)."""
        names: dict[FeatureKey, list[str]] = {}
        for name, uses in self.wants.items():
            if ":" not in name and name.startswith("/"):
                for key, _ in uses:
                    names.setdefault(key, []).append(name)
        if self.sim_time and self.clock is None:
            log.warning("no /clock yet (--sim-time): no state is made before its first tick")
        unbound = sorted({p.topic for t, p in self.seen.items() if t not in self.taken})
        for key in self.processor.keys:
            if not self.feeding.get(key):
                looked = ", ".join(names.get(key, [])[:4]) or "no topic specification"
                log.warning(
                    "no publisher yet for %s (it binds by %s); %s",
                    key,
                    looked,
                    f"publishers seen: {', '.join(unbound[:8])}{' …' if len(unbound) > 8 else ''}"
                    if unbound
                    else "no ROS 2 publisher seen (is --connect a router or robot, "
                    "--domain right, --bridge needed?)",
                )

    def idle(self) -> float:
        """How long to wait for the next event: on the wall clock, no longer than until the
        watermark (which moves at most as fast as the wall clock between events) can reach
        the next state due: a state waits for its delay, not for the next sample."""
        mark = self.watermark()
        if self.sim_time or mark is None:
            return 0.1
        return min(0.1, max(0.0, (self.processor.quiet_until - mark) / NS))

    def handle(self, event: tuple[Any, ...]) -> list[Event]:
        try:
            if event[0] == "sample":
                return self._sample(*event[1:])
            return self._token(event[1], event[2])
        except WireError as exc:
            self._reject(event[1] if event[0] == "sample" else "tokens", exc.kind, str(exc))
        except RecordError:
            raise  # ours, not the peer's: the run stops
        except DkError as exc:  # a value the formulas cannot use
            self._reject(event[1], "value", str(exc))
        return []

    def _reject(self, where: str, kind: str, why: str) -> None:
        """Counted per key and kind; logged at 1, 10, 100… of each."""
        sub = self.subs.get(where)
        shown = sub.topic if sub is not None else where
        n = self.rejected[(shown, kind)] = self.rejected.get((shown, kind), 0) + 1
        if loop.logged(n):
            log.warning("rejected %s (%s, %d so far): %s", shown, kind, n, why)

    def _warn(self, *why: str) -> None:
        if why not in self.warned:
            self.warned.add(why)
            log.warning("%s", " ".join(why))

    # ---- discovery -----------------------------------------------------------------------

    def _token(self, token: str, alive: bool) -> list[Event]:
        if not alive:
            return self._gone(token)
        pub = rmw.parse_token(token)
        if pub is None or token in self.seen:
            return []
        self.seen[token] = pub
        if pub.bridged and not self.bridge:
            self._warn(
                f"{pub.describe()}: announced by zenoh-bridge-ros2dds; skipped "
                f"(give --bridge to take it)"
            )
            return []
        if not pub.bridged and pub.domain != self.domain:
            return []
        if self.sim_time and pub.topic == CLOCK:
            return [] if self._another_layout(pub) else self._subscribe(pub, CLOCK, [])
        name = self._bound(pub)
        if name is None:
            return []
        if pub.msgtype not in self.store.fielddefs:
            self._warn(
                f"{pub.topic}: type {pub.msgtype} is not known (give its .msg file "
                f"with --msg, or --typestore); skipped"
            )
            return []
        if self._another_layout(pub):
            return []
        fits = []
        for key, m in self.wants[name]:
            why = (
                None
                if message_type_fits(pub.msgtype, m.msgtype)
                else f"carries {pub.msgtype}, but its specification says {m.msgtype}"
            )
            for f in (m.field, *(k for k, _ in m.filter)):
                why = why or fields.check(self.store.fielddefs, pub.msgtype, f)
            if why is not None:
                stream = stream_name(m.platform, m.topic)
                self._warn(f"{pub.topic} for {key} ({stream}): {why}; skipped")
            else:
                fits.append(key)
        return self._subscribe(pub, name, list(dict.fromkeys(fits))) if fits else []

    def _another_layout(self, pub: rmw.Publisher) -> bool:
        """Whether the type hash a publisher announces (rmw_zenoh's tokens carry REP-2011's)
        is not that of the definition used here, said in one warning: a type of the same
        name but another layout would be read as garbage (a CarMsg whose fields were
        reordered read speed 50 as 200.0).  A publisher announcing no hash is taken."""
        if pub.type_hash in (None, rmw.NO_HASH) or pub.msgtype not in self.store.fielddefs:
            return False
        ours = self.hashes.get(pub.msgtype)
        if ours is None:
            try:
                ours = self.store.hash_rihs01(pub.msgtype)
            except Exception:  # rosbags cannot hash this definition: nothing to compare
                ours = ""
            self.hashes[pub.msgtype] = ours
        if ours in ("", pub.type_hash):
            return False
        self._warn(
            f"{pub.describe()}: type hash {pub.type_hash} is not that of the definition "
            f"of {pub.msgtype} used here ({ours}): another layout; skipped (give --msg with "
            f"the definition it was built from)"
        )
        return True

    def _bound(self, pub: rmw.Publisher) -> str | None:
        """The recording name a publisher's topic binds by: under a `bind` namespace (its
        node's, or its topic's), as that platform's own name; else as the topic is named."""
        topic = self.remap.get(pub.topic, pub.topic)
        for platform, ns in self.bind.items():
            prefix = "" if ns == "/" else ns
            if topic.startswith(prefix + "/"):
                own = topic[len(prefix) :]
            elif pub.namespace is not None and (pub.namespace + "/").startswith(prefix + "/"):
                own = topic
            else:
                continue
            if f"{platform}:{own}" in self.wants:
                return f"{platform}:{own}"
        return next((n for n in (topic, topic[1:]) if n in self.wants), None)

    def _subscribe(self, pub: rmw.Publisher, name: str, features: list[FeatureKey]) -> list[Event]:
        import zenoh

        if name == CLOCK and pub.msgtype != CLOCK_TYPE:
            self._warn(f"{CLOCK}: type {pub.msgtype}, not {CLOCK_TYPE}; skipped")
            return []
        self.taken[pub.token] = pub.key
        sub = self.subs.get(pub.key)
        if sub is not None:
            sub.publishers.add(pub.token)
            return []
        wanted = (
            ["msg.clock.sec", "msg.clock.nanosec"] if name == CLOCK else self.processor.wanted[name]
        )
        read, stamped = ros_reader(
            self.store.fielddefs, pub.msgtype, wanted, False, self.store.deserialize_cdr
        )
        self.store.get_msgdef(pub.msgtype)  # rosbags' decoder built now, not at a sample
        sub = self.subs[pub.key] = _Sub(
            name, pub.topic, pub.msgtype, read, stamped, features, publishers={pub.token}
        )

        def take(sample: Any, key: str = pub.key) -> None:
            self._on_sample(key, sample)

        try:  # on sim time, samples and /clock ticks must keep their order across keys
            sub.handle = self.session.declare_subscriber(
                pub.key, direct(take) if self.sim_time else take
            )
        except zenoh.ZError as exc:
            del self.subs[pub.key], self.taken[pub.token]
            raise WireError(
                f"{pub.describe()}: cannot subscribe to {pub.key[:120]!r} ({str(exc)[:120]})",
                "token",
            ) from None
        now = self.now()
        changes: list[Event] = []
        for key in features:
            self.feeding.setdefault(key, set()).add(pub.key)
            m = next(m for k, m in self.wants[name] if k == key)
            role = "standing by: " if (name, key) in self.standby else ""
            changes.append(
                change("subscribed", now, m.platform, role + pub.describe(), str(key), m.topic)
            )
        return changes

    def _gone(self, token: str) -> list[Event]:
        pub = self.seen.pop(token, None)
        key = self.taken.pop(token, None)
        if pub is None or key is None:
            return []
        sub = self.subs[key]
        sub.publishers.discard(token)
        if sub.name == CLOCK:  # the next publisher to tick is followed (a player restarted)
            self.ticker = ()
        if sub.publishers:
            return []
        del self.subs[key]
        sub.handle.undeclare()
        now = self.now()
        platform, topic = next(
            ((m.platform, m.topic) for _, m in self.wants.get(sub.name, ())), ("", sub.topic)
        )
        changes: list[Event] = [
            change("unsubscribed", now, platform, f"{pub.describe()} went away", topic=topic)
        ]
        for feature in sub.features:
            feeding = self.feeding[feature]
            feeding.discard(key)
            if not feeding:
                changes.append(
                    change(
                        "source_lost",
                        now,
                        platform,
                        f"the last publisher of {sub.topic} went away",
                        feature=str(feature),
                        last_sample=self.processor.newest(feature),
                    )
                )
        return changes

    # ---- samples -------------------------------------------------------------------------

    def _sample(
        self, key: str, payload: bytes, attachment: bytes | None, arrival: int
    ) -> list[Event]:
        sub = self.subs.get(key)
        if sub is None:
            return _NO_EVENTS  # in flight when its subscription was dropped
        rmw.check_cdr(payload, MAX_PAYLOAD)
        if not sub.checked:  # a topic's first message decodes in full, or is refused
            decode(lambda raw: self.store.deserialize_cdr(raw, sub.msgtype), payload, sub.msgtype)
            sub.checked = True
        values = decode(sub.read, payload, sub.msgtype)
        if sub.name == CLOCK:
            return self._tick(values[0] * NS + values[1], attachment)
        source_time = None
        if attachment is not None:
            source_time = rmw.parse_attachment(attachment)[1]
            self.labelled = len(attachment) != rmw.PLAIN_SIZE
        stamped = sub.stamped and bool(values[-2] or values[-1])  # zero: never set
        if stamped:
            valid = values[-2] * NS + values[-1] + self.shift
        elif self.sim_time:
            valid = self.clock if self.clock is not None else arrival
        else:
            valid = source_time if source_time is not None else arrival
        available = (self.clock if self.clock is not None else valid) if self.sim_time else arrival
        if valid - available > EARLY_NS:  # not taken: it would end the data for every topic
            self.processor.early(sub.name, available, valid, values)
            return _NO_EVENTS
        self.processor.put(sub.name, available, valid, values)
        self.received += 1
        sub.arrived, sub.last_valid = arrival, valid
        if valid > sub.newest:
            sub.newest = valid
        if self.recorder is not None:
            self.recorder.message(
                sub.topic,
                sub.msgtype,
                available if stamped else valid,
                source_time if source_time is not None else arrival,
                payload,
            )
        return _NO_EVENTS

    def _tick(self, t: int, attachment: bytes | None) -> list[Event]:
        """/clock at `t`, as ROS takes it, but from one publisher: the first one heard (until
        a /clock publisher goes away); other publishers' ticks are said and left (one tick
        at 2^31 - 1 s from any node made every formula unknown).  Going back is a reset (a
        simulator restarted, `ros2 bag play` again): said once, and /clock time is shifted
        so that the stream goes on from where it was, its states and verdicts kept and
        the samples after it not late."""
        gid = rmw.parse_attachment(attachment)[2] if attachment is not None else None
        if not self.ticker:
            self.ticker = (gid,)
        elif self.ticker != (gid,):
            self.foreign_ticks += 1
            if loop.logged(self.foreign_ticks):
                log.warning(
                    "/clock: ticks from more than one publisher: only the first one's are "
                    "followed (%d others' so far; the last at %s s)",
                    self.foreign_ticks,
                    seconds(t),
                )
            return _NO_EVENTS
        events = _NO_EVENTS
        if self.last_tick is not None and t < self.last_tick and self.clock is not None:
            self.shift = self.clock - t
            events = [
                change(
                    "clock_reset",
                    self.clock,
                    "",
                    f"it went back from {seconds(self.last_tick)} s to {seconds(t)} s; the stream "
                    f"goes on from {seconds(self.clock)} s",
                )
            ]
        self.last_tick = t
        self.clock = t + self.shift
        return events

    def close(self) -> None:
        for handle in [*self.declared, *(s.handle for s in self.subs.values())]:
            handle.undeclare()
        self.declared, self.subs = [], {}
