"""A run watched in Foxglove as it goes (`monitor --foxglove [HOST:]PORT`): a Foxglove
WebSocket server (foxglove-sdk) that a user opens as `ws://localhost:PORT`.

It serves each monitored ground feature's values on its own JSON channel,
`/dkreason/feature/NAME/ARG…` (`{"value": …}` at the state's time: a Plot panel reads
`/dkreason/feature/Speed/car1.value`), the verdicts, instance verdicts, violations and
federation changes as `foxglove.Log` on `/dkreason/log` (eventlog.py, what the Log panel
reads) and as structured JSON on `/dkreason/events`, the channels `--record` writes.  A
replay of recordings waits for the first subscription (`ready`), so nothing is served to
nobody; a live run serves from the start.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from ..errors import DkError
from ..eventlog import LOG_SCHEMA, LOG_TOPIC, EventLog, ns
from ..model import FeatureKey
from .record import EVENT_SCHEMA, EVENTS

if TYPE_CHECKING:
    from foxglove.websocket import ChannelView, Client, ServerListener

FEATURE_SCHEMA: dict[str, Any] = {
    "title": "dkreason feature",
    "description": "A ground feature's value in the state made at the message's log time",
    "type": "object",
    "properties": {"value": {"type": ["number", "boolean", "string"]}},
}


def address(given: str) -> tuple[str, int]:
    """`[HOST:]PORT` (an IPv6 host in brackets) as (host, port); the host defaults to
    127.0.0.1, port 0 is one the system chooses."""
    host, sep, port = given.rpartition(":")
    host = host.strip("[]") if sep else "127.0.0.1"
    if not port.isdigit() or int(port) > 65535 or not host:
        raise DkError(f"--foxglove {given!r}: expected [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765")
    return host, int(port)


def topic(key: FeatureKey) -> str:
    """A feature's channel: `Speed[car1]` → `/dkreason/feature/Speed/car1`."""
    return "/".join(("/dkreason/feature", key.name, *key.args))


class Viewer:
    """A Foxglove WebSocket server for one run; `state` and `event` are what the monitor
    tells it (monitor.Watcher), `close` stops it."""

    def __init__(self, given: str, features: Iterable[FeatureKey] = (), name: str = "dkreason"):
        import foxglove  # loaded when serving: `dkreason --help` stays light

        host, port = address(given)
        self.host = host
        self.context = foxglove.Context()
        self.subscriptions = Subscriptions()
        self.said = EventLog()
        self.last = 0  # the time of the latest state (ns): an event without one is said then
        try:
            self.server = foxglove.start_server(
                name=name,
                host=host,
                port=port,
                context=self.context,
                server_listener=_listener(self.subscriptions),
            )
        except RuntimeError as exc:  # the port taken, the host unknown
            text = str(exc).removeprefix("FoxgloveError: ")
            raise DkError(f"--foxglove {given}: {text}") from None
        self.log = self._open(LOG_TOPIC, "foxglove.Log", LOG_SCHEMA)
        self.events = self._open(EVENTS, "dkreason/Event", EVENT_SCHEMA)
        self.channels: dict[FeatureKey, Any] = {}
        for key in features:
            self._channel(key)

    @property
    def url(self) -> str:
        """Where Foxglove opens the run (`ws://localhost:PORT` when served on every
        interface or on loopback)."""
        shown = "localhost" if self.host in ("0.0.0.0", "::", "127.0.0.1", "::1") else self.host
        return f"ws://{f'[{shown}]' if ':' in shown else shown}:{self.server.port}"

    def _open(self, topic: str, name: str, schema: dict[str, Any]) -> Any:
        """A JSON channel whose schema has the name panels look for (`foxglove.Log`)."""
        import foxglove

        data = json.dumps(schema).encode()
        described = foxglove.Schema(name=name, encoding="jsonschema", data=data)
        return foxglove.Channel(
            topic, schema=described, message_encoding="json", context=self.context
        )

    def _channel(self, key: FeatureKey) -> Any:
        channel = self.channels[key] = self._open(topic(key), "dkreason/Feature", FEATURE_SCHEMA)
        return channel

    def ready(self) -> None:
        """Wait until a client subscribes to a channel (a replay starts then)."""
        self.subscriptions.wait(1, None)

    def subscribed(self, channels: int, timeout: float) -> bool:
        """Whether clients subscribed to `channels` channels within `timeout` s (a client
        subscribing to several: a replay waits for the first only)."""
        return self.subscriptions.wait(channels, timeout)

    def state(
        self, time: int, values: Mapping[FeatureKey, Any], fresh: tuple[FeatureKey, ...] | None
    ) -> None:
        """A state at `time` (ns): the values of the features sampled at it (`fresh` None:
        of all that have one) on their channels."""
        self.last = time
        for key in values if fresh is None else fresh:
            value = values.get(key)
            if value is not None:
                channel = self.channels.get(key) or self._channel(key)
                channel.log(_json({"value": value}), log_time=time)

    def event(self, event: Any) -> None:
        """A verdict, violation or change: its log lines, and its JSON on the events
        channel, at its own time (at the latest state's when it has none)."""
        for at, line in self.said.lines(event, self.last):
            self.log.log(_json(line), log_time=at)
        at = ns(getattr(event, "time", None), self.last)
        self.events.log(_json(event.to_json()), log_time=at)

    def close(self) -> None:
        """Stop serving once the clients have left, or LINGER s after the run: foxglove-sdk
        sends on its own threads, and stopping at once reset connections before the last
        messages — the verdicts — reached them."""
        self.subscriptions.left(LINGER)
        self.server.stop()


def _json(message: dict[str, Any]) -> bytes:
    return json.dumps(message, ensure_ascii=False, default=_plain).encode()


def _plain(value: Any) -> Any:
    """An exact number (Fraction, Decimal) as JSON reads one."""
    return float(value)


LINGER = 5.0  # s a server waits at the end for its clients to take the last messages and go


class Subscriptions:
    """How many channel subscriptions the server has taken, and how many are held now (a
    client leaving drops its own), to wait on."""

    def __init__(self) -> None:
        self.count = 0
        self.held = 0
        self.changed = threading.Condition()

    def add(self, n: int) -> None:
        with self.changed:
            self.count += max(n, 0)
            self.held += n
            self.changed.notify_all()

    def wait(self, count: int, timeout: float | None) -> bool:
        with self.changed:
            return self.changed.wait_for(lambda: self.count >= count, timeout)

    def left(self, timeout: float) -> bool:
        """Whether every subscription was dropped within `timeout` s."""
        with self.changed:
            return self.changed.wait_for(lambda: self.held <= 0, timeout)


def _listener(subscriptions: Subscriptions) -> ServerListener:
    """foxglove-sdk's ServerListener (its other callbacks do nothing): each subscription is
    counted, and each dropped (a client leaving drops its own)."""
    from foxglove.websocket import ServerListener

    class Listener(ServerListener):
        def on_subscribe(self, client: Client, channel: ChannelView) -> None:
            subscriptions.add(1)

        def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
            subscriptions.add(-1)

    return Listener()
