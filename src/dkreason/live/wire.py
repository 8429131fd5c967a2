"""The federation's wire format: what `dkreason serve` and `monitor --live` put on Zenoh.

Key expressions, for platform P (every payload is UTF-8 JSON):

    dkreason/P/alive          liveliness token: P is present
    dkreason/P/ontology       query → {"file": "platform2.owl", "turtle": "<the ontology>"}:
                              always Turtle, whatever syntax the platform's file is in
    dkreason/P/specs          query → {"sslt": "<every topic specification, SSL_T>"}
    dkreason/P/objects        query → {"<object IRI>": {"sorts": ["<sort IRI>", …], "id": 12}}
    dkreason/P/changed        put {"version": n}: P's specs or objects changed; ask again
    dkreason/P/topic/T        put {"valid": ns, "available": ns, "msg": {…}}: a message of T,
                              or {"clock": ns}: every message of T up to this time is sent,
                              or {"clock": ns, "end": true}: T's replay ended, nothing follows

Times are integer nanoseconds on the stream's clock (a replay keeps its recording's times).
The clock travels on each topic's own key because Zenoh keeps the order of one key's puts,
not across keys (their callbacks run on different threads).
A peer's payload is untrusted: `decode` bounds its size and shape.  It is read by orjson
(a sample in ~0.3 µs, where `json` takes ~2); what orjson refuses (NaN, another encoding than
UTF-8, nesting past 1,024) goes to `json` as before, so it is read or refused alike; an
integer past 64 bits (beyond any ROS type) arrives as a float.  Payloads are written by
orjson too (`encode`).  A node that signs puts each topic payload with its signature as the
attachment (signing.py).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import orjson

from ..errors import ParseError, Span, WireError
from ..inputs.files import json_value

MAX_SAMPLE = 64 * 1024  # bytes of one sample or clock payload
MAX_KNOWLEDGE = 16 * 1024 * 1024  # bytes of one ontology, specs or objects reply
ROOT = "dkreason"


@dataclass(frozen=True, slots=True)
class Limits:
    """What one platform's knowledge may hold, checked before it is parsed or stored: bytes
    alone let a peer answering as a platform send 100,000 topics in 8 MB, which took 2 GB
    and minutes to load.  A reply past a limit refuses that platform only."""

    reply_bytes: int = MAX_KNOWLEDGE  # of each reply
    topics: int = 10_000  # topic specifications
    objects: int = 50_000  # (object, sort) memberships: the ontology's and the announced

    def check(self, p: str, what: str, count: int, limit: int) -> None:
        if count > limit:
            raise WireError(f"{p}'s {what}: more than {limit:,} (--max-peer-{what})", "limit")


LIMITS = Limits()  # the defaults


def key(platform: str, *parts: str) -> str:
    return "/".join((ROOT, platform, *parts))


def platform_of(key_expr: str) -> str:
    """P of `dkreason/P/…`."""
    return key_expr.split("/")[1]


_ENCODER = json.JSONEncoder(ensure_ascii=False, separators=(",", ":"))  # made once, not per put


def encode(value: Any) -> bytes:
    """Compact UTF-8 JSON, by orjson (~0.2 µs a sample; NaN and the infinities become null,
    which a reader takes as unknown as it does them); what orjson cannot write (an integer
    past 64 bits, a type of its own) by `json`, as before."""
    try:
        return orjson.dumps(value, option=orjson.OPT_NON_STR_KEYS)
    except TypeError:
        return _ENCODER.encode(value).encode()


def decode(payload: bytes, limit: int, what: str) -> Any:
    """A peer's JSON payload; any failure (size, syntax, encoding, nesting, a number too long)
    is a WireError."""
    if len(payload) > limit:
        raise WireError(f"{what}: {len(payload)} bytes, more than the {limit} allowed", "size")
    try:
        return orjson.loads(payload)
    except orjson.JSONDecodeError:
        pass  # not strict UTF-8 JSON: read (or refused, saying why) as it always was
    try:
        return json_value(payload, Span(what), exact=False)
    except ParseError as exc:
        raise WireError(f"{what}: {exc.message}", "json") from None


END = object()  # the msg of an end-of-replay tick


def topic_message(payload: bytes, what: str) -> tuple[int, int, Any]:
    """(available, valid, msg) of a topic's put; a clock tick has msg None, the tick that ends
    a replay msg END."""
    data = decode(payload, MAX_SAMPLE, what)
    if isinstance(data, dict) and "clock" in data:
        t = _time(data["clock"], what)
        return t, t, END if data.get("end") is True else None
    if not isinstance(data, dict) or not isinstance(data.get("msg"), dict):
        raise WireError(
            f'{what}: expected {{"valid": ns, "msg": {{…}}}} or {{"clock": ns}}', "shape"
        )
    valid = _time(data.get("valid"), what)
    available = _time(data.get("available", valid), what)
    return available, valid, data["msg"]


def _time(value: Any, what: str) -> int:
    if type(value) is not int:
        raise WireError(f"{what}: times must be integer nanoseconds, not {str(value)[:40]}", "time")
    return value
