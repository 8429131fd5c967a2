"""A platform node: one robot's knowledge and topics on the network (thesis 1.2, 4.3).

It answers queries for its ontology, topic specifications and objects, holds a liveliness
token while it runs, publishes its topics' samples, and says when its knowledge changed (an
API call, or its specs file edited by `dkreason specs add/remove`).  Samples come from the
Python API (`publish`) or a replay (`replay`) that keeps the recording's times and paces them
on a shared wall-clock origin, so nodes started apart replay in step and a restarted node
resumes where the others are.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import DkError
from ..manager import KnowledgeManager
from ..model import IdValue, TopicSpec
from ..parse.owl import served
from ..stream.sources import Record
from ..stream.units import NS
from . import wire
from .signing import Signer

log = logging.getLogger("dkreason.live")


class PlatformNode:
    def __init__(
        self,
        km: KnowledgeManager,
        session: Any,
        heartbeat: float = 0.02,
        sign: Signer | None = None,
    ) -> None:
        """`sign`: the key samples and knowledge replies are signed with (signing.signer)."""
        self.km, self.session, self.sign = km, session, sign
        self.name = km.local
        self.heartbeat = heartbeat
        self.lock = threading.RLock()  # orders samples before the clock that covers them
        self.version = 0
        self.publishers: dict[str, Any] = {}
        self.specs_stamp = self._stamp()
        self.closed = threading.Event()
        platform = km.kb.platform(self.name)
        main = Path(platform.ontology.file)
        text, digest = self._served(main)
        self._ontology = wire.encode({"file": main.name, "turtle": text, "digest": digest})
        self._answers = {
            "ontology": lambda: self._ontology,
            "specs": self._specs,
            "objects": self._objects,
        }
        self.queryables = [
            session.declare_queryable(
                wire.key(self.name, what), lambda query, what=what: self._answer(query, what)
            )
            for what in self._answers
        ]
        self.changes = session.declare_publisher(wire.key(self.name, "changed"))
        self.token = session.liveliness().declare_token(wire.key(self.name, "alive"))

    # ---- knowledge ---------------------------------------------------------------------

    def _served(self, main: Path) -> tuple[str, str]:
        """The platform's ontology with what it imports, as the config says to read it."""
        config = self.km.kb.config
        if config is not None:
            for files in config.platforms:
                if files.name == self.name:
                    return served(files.ontology, config.imports, files.skip_imports)
        return served((main,))  # a knowledge base built without a config: its one file

    def _answer(self, query: Any, what: str) -> None:
        """A knowledge reply; signed for the query's challenge (its attachment) when the
        node signs, so a reply recorded earlier cannot answer a later query."""
        with self.lock:
            payload = self._answers[what]()
        key_expr = wire.key(self.name, what)
        if self.sign is None:
            query.reply(key_expr, payload)
            return
        challenge = b"" if query.attachment is None else query.attachment.to_bytes()
        query.reply(key_expr, payload, attachment=self.sign.reply(challenge, key_expr, payload))

    def _specs(self) -> bytes:
        from ..parse.sslt import format_spec

        return wire.encode(
            {"sslt": "".join(f"{format_spec(s)}\n" for s in self.km.list_topic_specifications())}
        )

    def _objects(self) -> bytes:
        p = self.km.kb.platform(self.name)
        sorts: dict[str, list[str]] = {o: [] for o in sorted(p.ontology.individuals)}
        for o, c in p.ontology.types:
            sorts[o].append(c)
        kb = self.km.kb
        return wire.encode(
            {o: {"sorts": s, "id": kb.object_id(p.name, o)} for o, s in sorts.items()}
        )

    def _changed(self) -> None:
        self.version += 1
        self.changes.put(wire.encode({"version": self.version}))

    def add_topic(self, spec: str | TopicSpec) -> TopicSpec:
        with self.lock:
            added = self.km.add_topic(spec)
            self.specs_stamp = self._stamp()
            self._changed()
        return added

    def remove_topic(self, name: str) -> TopicSpec:
        with self.lock:
            removed = self.km.remove_topic(name)
            self.specs_stamp = self._stamp()
            self._changed()
        return removed

    def add_object(self, name: str, sort: str, id_: IdValue | None = None) -> str:
        """A new object of a sort, announced (not written to the ontology file)."""
        with self.lock:
            iri = self.km.kb.add_object(self.name, name, sort, id_)
            self._changed()
        return iri

    def _stamp(self) -> tuple[int, int] | None:
        path = self.km.kb.platform(self.name).specs_path
        try:
            info = path.stat() if path is not None else None
        except OSError:
            return None
        return (info.st_mtime_ns, info.st_size) if info else None

    def _reload_specs(self) -> None:
        """The specs file changed on disk (`dkreason specs add`): take it if it checks."""
        from ..parse.sslt import read_specs

        stamp = self._stamp()
        if stamp == self.specs_stamp:
            return
        path = self.km.kb.platform(self.name).specs_path
        assert path is not None
        with self.lock:
            self.specs_stamp = stamp
            try:
                added, removed = self.km.kb.replace_specs(self.name, list(read_specs(path).specs))
            except DkError as exc:
                log.warning(
                    "%s: specs file not taken, keeping the previous specs: %s", self.name, exc
                )
                return
            if added or removed:
                log.info(
                    "%s: specs file changed: added %s, removed %s",
                    self.name,
                    ", ".join(added) or "none",
                    ", ".join(removed) or "none",
                )
                self._changed()

    # ---- samples -----------------------------------------------------------------------

    def publish(
        self,
        topic: str,
        msg: dict[str, Any],
        valid: int | None = None,
        available: int | None = None,
    ) -> None:
        """A message of `topic`; times in ns on the stream clock (default: now)."""
        with self.lock:
            now = time.time_ns() if valid is None else valid
            self._put(topic, now if available is None else available, now, msg)

    def _publisher(self, topic: str) -> Any:
        pub = self.publishers.get(topic)
        if pub is None:
            import zenoh

            pub = self.publishers[topic] = self.session.declare_publisher(
                wire.key(self.name, "topic", topic),
                congestion_control=zenoh.CongestionControl.BLOCK,
            )
        return pub

    def _put(self, topic: str, available: int, valid: int, msg: Any) -> None:
        self._send(topic, wire.encode({"valid": valid, "available": available, "msg": msg}))

    def _send(self, topic: str, payload: bytes) -> None:
        """Put `payload` on the topic's key, signed when the node has a key."""
        if self.sign is None:
            self._publisher(topic).put(payload)
        else:
            key_expr = wire.key(self.name, "topic", topic)
            self._publisher(topic).put(payload, attachment=self.sign.sample(key_expr, payload))

    def _clock(self, now: int, end: bool = False) -> None:
        """Tell every topic (specified or published) that all of it up to `now` is sent (and
        with `end`, that nothing follows: the replay is over)."""
        tick = wire.encode({"clock": now, "end": True} if end else {"clock": now})
        for topic in {*self.km.list_topics(), *self.publishers}:
            self._send(topic, tick)

    def feed(self, records: Iterator[Record], watch: float = 0.5) -> None:
        """Publish `records` as they come (a JSON-lines pipe): their times are the clock."""
        next_watch = next_tick = time.monotonic()
        last = None
        for topic, available, valid, msg in _own(records, self.name):
            if self.closed.is_set():
                return
            with self.lock:
                self._put(topic, available, valid, msg)
                last = available
                if time.monotonic() >= next_tick:  # the others have nothing before it
                    self._clock(available)
                    next_tick = time.monotonic() + self.heartbeat
            if time.monotonic() >= next_watch:
                self._reload_specs()
                next_watch = time.monotonic() + watch
        if last is not None and not self.closed.is_set():
            with self.lock:
                self._clock(last, end=True)  # the input is over: so is its stream
        self.closed.wait()

    def serve(
        self,
        records: Iterator[Record] | None = None,
        origin: float | None = None,
        speed: float = 1.0,
        watch: float = 0.5,
    ) -> None:
        """Replay `records` (or only keep the clock, on wall time) until `close`.

        A record made at time t is published at wall time origin + (t - first)/speed with
        its own times; records already past (a node restarted mid-run) are skipped."""
        origin = time.time() if origin is None else origin
        pending = _own(records, self.name) if records is not None else iter(())
        head = next(pending, None)
        first = head[1] if head is not None else 0
        replaying = records is not None

        def stream_now() -> int:
            if not replaying:
                return time.time_ns()
            return first + int((time.time() - origin) * speed * NS)

        skipped, start = 0, stream_now()
        while head is not None and head[1] < start:
            head, skipped = next(pending, None), skipped + 1
        if skipped:
            log.info(
                "%s: replay resumes at %.3f s, %d earlier messages skipped",
                self.name,
                start / NS,
                skipped,
            )
        next_watch = time.monotonic() + watch
        last = start
        while not self.closed.is_set():
            now = stream_now()
            with self.lock:
                while head is not None and head[1] <= now:
                    last = head[1]
                    self._put(*head)
                    head = next(pending, None)
                if replaying and head is None:  # the recording is over: so is its stream
                    self._clock(last, end=True)
                    log.info("%s: replay ended at %.3f s", self.name, last / NS)
                    break
                self._clock(now if head is None else min(now, head[1] - 1))
            if time.monotonic() >= next_watch:
                self._reload_specs()
                next_watch = time.monotonic() + watch
            wait = self.heartbeat
            if head is not None:
                wait = min(wait, max(0.0, (head[1] - stream_now()) / speed / NS))
            self.closed.wait(wait)
        self.closed.wait()  # knowledge is still answered until the node is stopped

    def close(self) -> None:
        self.closed.set()
        with self.lock:
            self.token.undeclare()
            for q in self.queryables:
                q.undeclare()


def _own(records: Iterator[Record], platform: str) -> Iterator[Record]:
    """This platform's topics in a recording, by their names: `/P/T` or `T` → T."""
    prefix = f"/{platform}/"
    for topic, available, valid, msg in records:
        if topic.startswith(prefix):
            yield topic[len(prefix) :], available, valid, msg
        elif topic.strip("/").count("/") == 0:
            yield topic.strip("/"), available, valid, msg
