"""Monitor a live federation, adapting as it changes (thesis 8.2's future work, built).

The monitor finds the platforms its config names by their liveliness tokens, asks each for its
knowledge, matches with its own mapping files, and subscribes to the relevant topics only.
Whenever a platform comes or goes, or announces new specs or objects, the change goes into the
knowledge base as facts (only the views that read them are derived again), the formulas are
matched again, and subscriptions are added or dropped; the progressor and every feature's
history carry on, so decided verdicts stay.  A feature left with no topic is reported, and its
value turns unknown once its last sample is older than the maximum age.

Time is the stream's: each subscribed topic's clock (its samples and clock ticks, which Zenoh
delivers in order on that topic's key) says up to when it has been sent, and a state is made
once every subscribed topic has passed its time (plus the policy's delay), so samples from
platforms running at different paces are never late for each other.  A topic just subscribed
holds the others back until its first tick, for at most `HOLD` seconds.

Trust: knowledge and samples are taken only from the platforms in the config; anything else
seen is logged once.  Payloads are bounded and checked (wire.py), knowledge by what it holds
too (`wire.Limits`: topics, objects), signatures when the platform must sign (signing.py:
knowledge replies signed for the monitor's challenge, samples under the node's current
nonce); a bad one is logged and dropped, a bad knowledge reply refuses that platform only.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Iterator, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

from ..errors import DkError, WireError
from ..kb import Platform, make_platform, with_objects
from ..manager import KnowledgeManager
from ..model import FeatureKey, StreamRequest, TopicSpec
from ..monitor import Monitor, Watch
from ..plan import Parsed, parse
from ..stream.policy import StreamPolicy
from ..stream.processor import StreamProcessor
from ..stream.sources import dict_reader
from ..stream.units import NS
from . import loop, wire
from .change import Event, change
from .inbox import Inbox
from .signing import NONCE, check_trust, verify_reply, verify_sample

log = logging.getLogger("dkreason.live")
HOLD = 1.0  # wall seconds a new subscription may hold back states before its first tick


def configured(km: KnowledgeManager) -> set[str]:
    """The platforms a live monitor trusts by name: its config's (online or not yet)."""
    config = km.kb.config
    return {p.name for p in config.platforms} if config else set(km.kb.platforms)


class LiveMonitor:
    def __init__(
        self,
        km: KnowledgeManager,
        formulas: Sequence[str | Parsed],
        policy: StreamPolicy,
        session: Any,
        wait: float = 10.0,
        ask_timeout: float = 3.0,
        trust: dict[str, Any] | None = None,
        limits: wire.Limits = wire.LIMITS,
        watch: Watch | None = None,
    ) -> None:
        """`km`: the knowledge at hand (`KnowledgeManager.from_config(path, live=True)`: the
        platforms whose files the config names, none online); the others' is asked of their
        nodes as they appear.  The platforms its config names are the only ones trusted.
        `trust`: platform → Ed25519 public key (signing.trusted_keys); the knowledge and
        samples of those platforms must be signed by it, and every one must be a platform of
        the config.  `limits`: what one platform's knowledge may hold.  `watch`: told each
        state (a Foxglove viewer)."""
        self.formulas = parse(formulas)  # a typo is reported at once, not after the wait
        self.km, self.policy, self.session = km, policy, session
        self.wait, self.ask_timeout, self.limits = wait, ask_timeout, limits
        self.names = configured(km)
        if trust is not None:
            check_trust(trust, self.names, "trust")
        self.trust, self.watch = trust or {}, watch
        self.nonces: dict[str, bytes] = {}  # platform → its signing node's current run
        self.digests: dict[str, str] = {}  # of the ontology each platform served
        self.inbox = Inbox()
        self.present: set[str] = set()
        self.clocks: dict[tuple[str, str], int] = {}  # (platform, topic) → sent up to
        self.ended: dict[tuple[str, str], int] = {}  # (platform, topic) → its replay's end
        self.since: dict[tuple[str, str], float] = {}  # (platform, topic) → subscribed at
        self.seen_strangers: set[str] = set()  # the first few, named in the log
        self.strangers = 0
        self.rejected: dict[tuple[str, str, str], int] = {}
        self.subs: dict[tuple[str, str], Any] = {}  # (platform, topic) → subscriber
        self.topics: dict[FeatureKey, set[tuple[str, str]]] = {}  # → its (platform, topic)s
        # the engine, once the local platform's knowledge is there to plan the formulas on
        self.monitor: Monitor | None = None
        self.processor: StreamProcessor | None = None
        self.source = loop.LiveSource()
        self.read = dict_reader(self.source.name, {})  # a message's wanted fields
        self.end: int | None = None  # ns: samples after it are not taken
        self.received = 0  # samples taken
        self.stop = threading.Event()
        self.declared = [
            session.liveliness().declare_subscriber(
                f"{wire.ROOT}/*/alive", self._on_alive, history=True
            )
        ]
        for p in sorted(self.names):
            self.declared.append(
                session.declare_subscriber(
                    wire.key(p, "changed"),
                    lambda s, p=p: self.inbox.put(("changed", p, s.payload.to_bytes())),
                )
            )

    # ---- zenoh callbacks (other threads): only enqueue ----------------------------------

    def _on_alive(self, sample: Any) -> None:
        import zenoh

        p = wire.platform_of(str(sample.key_expr))
        self.inbox.put(("alive", p, sample.kind == zenoh.SampleKind.PUT))

    # ---- knowledge ---------------------------------------------------------------------

    def _ask(self, p: str, what: str) -> Any:
        """A platform's answer; a platform that signs must sign it for this query's challenge
        (other replies, a stranger's or one recorded earlier, are passed over)."""
        key_expr, key = wire.key(p, what), self.trust.get(p)
        challenge = os.urandom(NONCE)
        refused: WireError | None = None
        for reply in self.session.get(key_expr, timeout=self.ask_timeout, attachment=challenge):
            if reply.ok is None:
                continue
            payload = reply.ok.payload.to_bytes()
            if key is not None:
                signature = reply.ok.attachment
                try:
                    self.nonces[p] = verify_reply(
                        key,
                        challenge,
                        key_expr,
                        payload,
                        None if signature is None else signature.to_bytes(),
                    )
                except WireError as exc:
                    refused = exc
                    continue
            return wire.decode(payload, self.limits.reply_bytes, f"{p}'s {what}")
        raise refused or WireError(f"{p} did not answer the query for its {what}")

    def _ontology(self, p: str) -> dict[str, str]:
        ont = self._ask(p, "ontology")
        if (
            not isinstance(ont, dict)
            or not isinstance(ont.get("turtle"), str)
            or not isinstance(ont.get("file"), str)
        ):
            raise WireError(f'{p}\'s ontology: expected {{"file": …, "turtle": …}}')
        return {"file": ont["file"], "text": ont["turtle"], "digest": str(ont.get("digest"))}

    def _fetch(self, p: str, ont: dict[str, str] | None = None) -> Platform:
        """A platform's whole knowledge, asked over the network (the ontology reply may be
        at hand already)."""
        from ..parse.owl import parse_ontology

        ont = ont or self._ontology(p)
        name = Path(ont["file"]).name or "ontology"  # shown in messages only
        ontology = parse_ontology(
            ont["text"].encode(), f"{wire.key(p, 'ontology')}/{name}", p, fmt="turtle"
        )
        told = set(ontology.types)
        new = {(iri, sort): id_ for iri, sort, id_ in self._objects(p) if (iri, sort) not in told}
        self.limits.check(p, "objects", len(told) + len(new), self.limits.objects)
        self.digests[p] = ont["digest"]
        ontology = with_objects(ontology, [(iri, sort, id_) for (iri, sort), id_ in new.items()])
        return make_platform(ontology, self._specs(p))

    def _specs(self, p: str) -> tuple[TopicSpec, ...]:
        """A platform's topic specifications, counted before they are parsed (every one
        says `contains`: the count bounds theirs)."""
        from ..parse.sslt import parse_text

        specs = self._ask(p, "specs")
        if not isinstance(specs, dict) or not isinstance(specs.get("sslt"), str):
            raise WireError(f'{p}\'s specs: expected {{"sslt": …}}')
        text = str(specs["sslt"])
        self.limits.check(p, "topics", text.count("contains"), self.limits.topics)
        return parse_text(text, wire.key(p, "specs")).specs

    def _objects(self, p: str) -> list[tuple[str, str, Any]]:
        objects = self._ask(p, "objects")
        out: list[tuple[str, str, Any]] = []
        for iri, info in objects.items() if isinstance(objects, dict) else ():
            sorts = info.get("sorts") if isinstance(info, dict) else None
            id_ = info.get("id") if isinstance(info, dict) else None
            if not isinstance(sorts, list) or not isinstance(id_, (int, str, type(None))):
                raise WireError(f"{p}'s objects: {iri!r} needs sorts and an id")
            out += [(iri, str(s), id_) for s in sorts]
            self.limits.check(p, "objects", len(out), self.limits.objects)
        return out

    def _update(self, p: str) -> None:
        """A known platform's specs and objects, asked again and applied as changes."""
        kb = self.km.kb
        specs = self._specs(p)
        types = set(kb.platform(p).ontology.types)
        new = [(iri, sort, id_) for iri, sort, id_ in self._objects(p) if (iri, sort) not in types]
        self.limits.check(p, "objects", len(types) + len(new), self.limits.objects)
        added, removed = kb.replace_specs(p, list(specs))
        kb.add_objects(p, [(f"<{iri}>", f"<{sort}>", id_) for iri, sort, id_ in new])
        if added or removed or new:
            log.info(
                "%s changed: specs added %s, removed %s; %d new object types",
                p,
                ", ".join(added) or "none",
                ", ".join(removed) or "none",
                len(new),
            )

    # ---- the loop ----------------------------------------------------------------------

    def run(self, until: Fraction | None = None, duration: float | None = None) -> Iterator[Event]:
        """Events as they happen, from the platforms joining before the local one is there,
        until every formula is decided, the stream clock passes `until` (s), `duration` (wall
        s, from the start) is over, every replay has ended, or `stop` is set; then the end
        verdicts."""
        yield from self._gather()
        monitor = self.monitor = Monitor(
            self.km.plan(self.formulas), self.km.matcher(self.policy), self.policy, watch=self.watch
        )
        processor = self.processor = monitor.start(self.source)
        for said in monitor.unsaid():
            log.warning("%s", said)
        monitor.follow = self._follow
        self.read = dict_reader(self.source.name, processor.wanted)
        yield from self._subscribe(monitor.request, None, "")
        yield from monitor.events()
        self.end = None if until is None else int(until * NS)
        yield from loop.run(monitor, processor, self, self.end, duration)
        for (p, what, kind), n in sorted(self.rejected.items()):
            log.warning("in all, rejected %d %s from %s (%s)", n, _plural(what, n), p, kind)

    def _gather(self) -> Iterator[Event]:
        """Wait up to `wait` s for the local platform's knowledge (formulas are written in its
        words); others join as they come."""
        local, platforms = self.km.local, self.km.kb.platforms
        deadline = time.monotonic() + self.wait
        while local not in platforms:
            left = deadline - time.monotonic()
            if left <= 0:
                raise DkError(
                    f"the local platform {local} did not appear within {self.wait:g} s "
                    f"(is `dkreason serve` running for it, on a reachable endpoint?)"
                )
            for event in self.inbox.drain(min(left, 0.1), most=1):  # the rest waits for run
                yield from self.handle(event)

    # ---- what the loop asks (loop.Feed) ------------------------------------------------

    def now(self) -> int | None:
        """The stream clock: up to when every subscribed topic has been sent."""
        return self.watermark()

    def watermark(self) -> int | None:
        """Up to when every subscribed topic has been sent (None: not known yet)."""
        clocks = []
        if self.over():
            return max(self.ended.values())
        for pt in self.subs:
            if pt in self.ended:  # nothing follows: it holds nobody back
                continue
            if pt in self.clocks:
                clocks.append(self.clocks[pt])
            elif time.monotonic() - self.since[pt] < HOLD:
                return None
        return min(clocks) if clocks else None

    def idle(self) -> float:
        return 0.1  # states wait for the platforms' clock ticks, not for the wall clock

    def over(self) -> bool:
        """Every subscribed topic's replay has ended: nothing more will come."""
        return bool(self.subs) and all(pt in self.ended for pt in self.subs)

    def tick(self) -> None:
        pass  # time is the platforms': nothing happens between their events

    def handle(self, event: tuple[Any, ...]) -> list[Event]:
        kind, p = event[0], event[1]
        if p not in self.names:
            self._stranger(p)
            return []
        try:
            if kind == "sample":
                self._sample(p, event[2], event[3], event[4], event[5])
            elif kind == "alive":
                return self._alive(p) if event[2] else self._left(p)
            elif kind == "changed" and p in self.present:
                return self._changed(p)
        except DkError as exc:  # a peer's bad payload or knowledge: its fault, not ours
            self._reject(p, kind, str(exc), getattr(exc, "kind", "knowledge"))
        except Exception as exc:
            if kind != "sample":
                raise
            self._reject(
                p, kind, f"unexpected {type(exc).__name__}: {str(exc)[:200]}", type(exc).__name__
            )
        return []

    def _stranger(self, p: str) -> None:
        """Platforms outside the config: the first few named, then only counted."""
        self.strangers += 1
        if len(self.seen_strangers) < 10 and p not in self.seen_strangers:
            self.seen_strangers.add(p)
            log.warning(
                "ignoring platform %s: not in the config%s",
                p,
                ""
                if len(self.seen_strangers) < 10
                else " (further unknown platforms are counted, not named)",
            )
        elif loop.logged(self.strangers) and self.strangers >= 100:
            log.warning(
                "ignored %d announcements or samples of platforms outside the config",
                self.strangers,
            )

    def _reject(self, p: str, what: str, why: str, kind: str = "knowledge") -> None:
        """Logged once per peer and kind of fault, then at 10, 100, 1000… rejections."""
        n = self.rejected[(p, what, kind)] = self.rejected.get((p, what, kind), 0) + 1
        if loop.logged(n):
            log.warning("rejected %s from %s (%s, %d so far): %s", what, p, kind, n, why)

    def _sample(
        self, p: str, topic: str, payload: bytes, signature: bytes | None, name: str
    ) -> None:
        """A sample of `name` (`p/topic`)."""
        pt = (p, topic)
        if p not in self.present or pt not in self.subs:
            return  # in flight when its subscription was dropped
        if p in self.trust:
            verify_sample(
                self.trust[p], self.nonces.get(p), wire.key(p, "topic", topic), payload, signature
            )
        available, valid, msg = wire.topic_message(payload, name)
        if msg is wire.END:
            self.ended[pt] = available
        elif msg is not None and (self.end is None or valid <= self.end):
            try:
                values = self.read(name, valid, msg)
            except DkError as exc:
                raise WireError(str(exc), "field") from None
            processor = self.processor
            assert processor is not None  # a subscription exists once it has started
            try:
                processor.put(name, available, valid, values)
            except DkError as exc:
                raise WireError(str(exc), "value") from None
            self.received += 1
        sent = self.clocks.get(pt)
        if sent is None or available > sent:
            self.clocks[pt] = available

    def _alive(self, p: str) -> list[Event]:
        if p in self.present:
            return []
        kb = self.km.kb
        if p not in kb.platforms:
            try:
                kb.add_platform(self._fetch(p))  # online
            except DkError as exc:
                self._reject(p, "knowledge", str(exc), getattr(exc, "kind", "knowledge"))
                return []
        else:
            try:
                self._refresh(p)
            except DkError as exc:
                self._reject(p, "knowledge", str(exc), getattr(exc, "kind", "knowledge"))
            kb.set_online(p, True)
        self.present.add(p)
        return [change("joined", self.watermark(), p), *self._rematch(p, f"platform {p} joined")]

    def _refresh(self, p: str) -> None:
        """A platform back again: a new ontology replaces what was known of it; otherwise
        only the differences in specs and objects are applied."""
        kb = self.km.kb
        before = self.digests.get(p)
        ont = self._ontology(p) if before is not None else None
        if ont is not None and ont["digest"] != before:
            if p == self.km.local:
                self.digests[p] = ont["digest"]
                log.warning(
                    "%s came back with another ontology; the formulas keep the one "
                    "they were checked against until restart",
                    p,
                )
            else:
                log.info("%s came back with another ontology: its knowledge is replaced", p)
                fresh = self._fetch(p, ont)
                kb.remove_platform(p)
                kb.add_platform(fresh)
                return
        self._update(p)

    def _left(self, p: str) -> list[Event]:
        if p not in self.present:
            return []
        changes: list[Event] = [change("left", self.watermark(), p)]
        self.present.discard(p)
        self.km.kb.set_online(p, False)
        return changes + self._rematch(p, f"platform {p} went away")

    def _changed(self, p: str) -> list[Event]:
        self._update(p)
        return self._rematch(p, f"platform {p} changed its topics")

    # ---- subscriptions -----------------------------------------------------------------

    def _rematch(self, p: str, why: str) -> list[Event]:
        """The formulas planned again (objects that joined their sorts get instances, judged
        from now on) and their features matched again; subscriptions follow.  Before the
        start, the first match subscribes."""
        if self.monitor is None or self.processor is None:
            return []
        try:
            started = self.monitor.extend(self.km.plan(self.formulas))
        except DkError as exc:  # the knowledge no longer fits a formula: it keeps its objects
            log.warning("after %s, the formulas keep their objects: %s", why, exc)
            started = []
        request = self.monitor.rematch(self.source)
        for said in self.monitor.unsaid():
            log.warning("%s", said)
        self.read = dict_reader(self.source.name, self.processor.wanted)
        now = self.watermark()
        return [
            *self._subscribe(request, p, why),
            *(change("instance", now, p, formula, feature=name) for formula, name in started),
        ]

    def _follow(self, request: StreamRequest) -> list[Event]:
        """The monitor set a source aside or took one back: the subscriptions follow (one set
        aside stays subscribed, so its return is seen, and with --best-source so do the
        topics standing by, so the features can be re-routed to them)."""
        assert self.processor is not None
        self.read = dict_reader(self.source.name, self.processor.wanted)
        return self._subscribe(request, None, "a source set aside or taken back")

    def _subscribe(self, request: StreamRequest, p: str | None, why: str) -> list[Event]:
        processor, monitor = self.processor, self.monitor
        assert processor is not None and monitor is not None  # called once started
        # a topic set aside is subscribed while its platform is there, so its return is seen
        # (a clock gone with its platform would hold the stream back)
        aside = [pt for pt in sorted(monitor.aside) if pt[0] in self.present]
        now = self.watermark()
        before = self.topics
        self.topics = {
            f.feature.key: {(t.platform, t.topic) for t in f.topics} for f in request.features
        }
        changes: list[Event] = []
        # (platform, topic) → (the feature it feeds, or stands by for under --best-source)
        wanted = (
            dict.fromkeys(aside, ("", ""))
            | {
                (t.platform, t.topic): (str(f.feature.key), "standing by")
                for f in request.features
                for t in f.standby
            }
            | {pt: (str(key), "") for key, pts in self.topics.items() for pt in pts}
        )
        for (q, t), (feature, role) in sorted(wanted.items()):
            if (q, t) not in self.subs:
                self.since[(q, t)] = time.monotonic()
                self.subs[(q, t)] = self.session.declare_subscriber(
                    wire.key(q, "topic", t),
                    lambda s, q=q, t=t, name=f"{q}/{t}": self.inbox.put(
                        (
                            "sample",
                            q,
                            t,
                            s.payload.to_bytes(),
                            None if s.attachment is None else s.attachment.to_bytes(),
                            name,
                        )
                    ),
                )
                changes.append(change("subscribed", now, q, role, feature=feature, topic=t))
        for q, t in sorted(set(self.subs) - set(wanted)):
            self.subs.pop((q, t)).undeclare()
            self.clocks.pop((q, t), None)
            changes.append(change("unsubscribed", now, q, why, topic=t))
        for key, pts in before.items():
            if pts and not self.topics.get(key):
                changes.append(
                    change(
                        "source_lost",
                        now,
                        p or "",
                        why,
                        feature=str(key),
                        last_sample=processor.newest(key),
                    )
                )
        return changes

    def close(self) -> None:
        for sub in [*self.declared, *self.subs.values()]:
            sub.undeclare()
        self.declared, self.subs = [], {}


def _plural(what: str, n: int) -> str:
    return what if n == 1 or what == "knowledge" else f"{what}s"
