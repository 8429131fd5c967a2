"""What crosses the network, and how a Zenoh session is opened.

Key expressions, for platform P (every payload is UTF-8 JSON):

    dkreason/P/alive          liveliness token: P is present
    dkreason/P/ontology       query → {"file": "platform2.owl", "text": "<the OWL document>"}
    dkreason/P/specs          query → {"sslt": "<every topic specification, SSL_T>"}
    dkreason/P/objects        query → {"<object IRI>": {"sorts": ["<sort IRI>", …], "id": 12}}
    dkreason/P/changed        put {"version": n}: P's specs or objects changed; ask again
    dkreason/P/topic/T        put {"valid": ns, "available": ns, "msg": {…}}: a message of T,
                              or {"clock": ns}: every message of T up to this time is sent

Times are integer nanoseconds on the stream's clock (a replay keeps its recording's times).
The clock travels on each topic's own key because Zenoh keeps the order of one key's puts,
not across keys (their callbacks run on different threads).
A peer's payload is untrusted: `decode` bounds its size and shape.
"""

from __future__ import annotations

import json
import re
from typing import Any

from ..errors import DkError

MAX_SAMPLE = 64 * 1024  # bytes of one sample or clock payload
MAX_KNOWLEDGE = 16 * 1024 * 1024  # bytes of one ontology, specs or objects reply
ROOT = "dkreason"
ENDPOINT = re.compile(r"^[a-z][a-z0-9+-]*/\S+$")


class WireError(DkError):
    """A peer sent something malformed: logged and dropped, never fatal."""


def key(platform: str, *parts: str) -> str:
    return "/".join((ROOT, platform, *parts))


def platform_of(key_expr: str) -> str:
    """P of `dkreason/P/…`."""
    return key_expr.split("/")[1]


def encode(value: Any) -> bytes:
    return json.dumps(value, ensure_ascii=False, separators=(",", ":")).encode()


def decode(payload: bytes, limit: int, what: str) -> Any:
    if len(payload) > limit:
        raise WireError(f"{what}: {len(payload)} bytes, more than the {limit} allowed")
    try:
        return json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise WireError(f"{what}: not JSON ({exc})") from None


def topic_message(payload: bytes, what: str) -> tuple[int, int, Any]:
    """(available, valid, msg) of a topic's put; a clock tick has msg None."""
    data = decode(payload, MAX_SAMPLE, what)
    if isinstance(data, dict) and "clock" in data:
        t = _time(data["clock"], what)
        return t, t, None
    if not isinstance(data, dict) or not isinstance(data.get("msg"), dict):
        raise WireError(f"{what}: expected {{\"valid\": ns, \"msg\": {{…}}}} or "
                        f"{{\"clock\": ns}}")
    valid = _time(data.get("valid"), what)
    available = _time(data.get("available", valid), what)
    return available, valid, data["msg"]


def _time(value: Any, what: str) -> int:
    if type(value) is not int:
        raise WireError(f"{what}: times must be integer nanoseconds, not {value!r}")
    return value


def open_session(connect: list[str], listen: list[str], config_file: str | None = None) -> Any:
    """A peer session on explicit endpoints; multicast scouting is off, so only the endpoints
    given (and peers they know) are reached.  A Zenoh config file may set the rest (TLS,
    access control)."""
    import zenoh

    for endpoint in (*connect, *listen):
        if not ENDPOINT.match(endpoint):
            raise DkError(f"zenoh: bad endpoint {endpoint!r} (expected <protocol>/<address>, "
                          f"e.g. tcp/192.168.1.10:7447)")
    try:
        config = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("connect/endpoints", json.dumps(connect))
        config.insert_json5("listen/endpoints", json.dumps(listen))
        return zenoh.open(config)
    except zenoh.ZError as exc:
        why = str(exc).split(" at /")[0][:300]
        raise DkError(f"zenoh: cannot open a session (connect {connect}, listen {listen}"
                      f"{', config ' + config_file if config_file else ''}): {why}") from None
