"""What crosses the network, and how a Zenoh session is opened.

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
orjson too (`encode`).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import orjson

from ..errors import DkError, ParseError, Span
from ..inputs.files import json_value, read_text

MAX_SAMPLE = 64 * 1024  # bytes of one sample or clock payload
MAX_KNOWLEDGE = 16 * 1024 * 1024  # bytes of one ontology, specs or objects reply
ROOT = "dkreason"
ENDPOINT = re.compile(r"^[a-z][a-z0-9+-]*/\S+$")


class WireError(DkError):
    """A peer sent something malformed: logged and dropped, never fatal.  `kind` (size, json,
    shape, time, field, value, knowledge) groups what is logged once per peer."""

    def __init__(self, message: str, kind: str = "knowledge") -> None:
        super().__init__(message)
        self.kind = kind


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


def direct(callback: Any) -> Any:
    """A callback zenoh calls on its own receiving task (zenoh-python's default hands each
    subscriber's samples to a thread of its own): samples of one session then reach the
    monitor in the order they were put, across keys (a ROS 2 message is never taken before the
    /clock tick put ahead of it), with no thread hop per sample.  It must only enqueue."""
    import zenoh

    return zenoh.handlers.Callback(callback, indirect=False)


def open_session(connect: list[str], listen: list[str], config_file: str | None = None) -> Any:
    """A peer session on explicit endpoints; multicast scouting is off, so only the endpoints
    given (and peers they know) are reached.  A Zenoh config file may set the rest (TLS,
    access control)."""
    import zenoh

    for endpoint in (*connect, *listen):
        if not ENDPOINT.match(endpoint):
            raise DkError(
                f"zenoh: bad endpoint {endpoint!r} (expected <protocol>/<address>, "
                f"e.g. tcp/192.168.1.10:7447)"
            )
    text = read_text(Path(config_file)) if config_file else None
    try:
        config = zenoh.Config.from_json5(text) if text is not None else zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("connect/endpoints", json.dumps(connect))
        config.insert_json5("listen/endpoints", json.dumps(listen))
        return zenoh.open(config)
    except zenoh.ZError as exc:
        why = _zenoh_error(str(exc), config_file)
        raise DkError(
            f"zenoh: cannot open a session (connect {connect}, listen {listen}"
            f"{', config ' + config_file if config_file else ''}): {why}"
        ) from None


def _zenoh_error(text: str, config_file: str | None) -> str:
    """Zenoh's error text in one line: a JSON5 syntax error as `line:column: expected …`."""
    where = re.match(r"\s*-->\s*(\d+:\d+)", text)
    expected = re.search(r"=\s*(.+)\s*$", text)
    if where and expected:
        return f"{config_file}:{where.group(1)}: {expected.group(1)}"
    return (text.split(" at /")[0].strip().splitlines() or [""])[0][:300]


# ---- signed samples: Ed25519 over the key expression and the payload ------------------------
# A node started with `--sign KEY` puts each topic payload with a 64-byte signature of
# `key expression + "\n" + payload` as the Zenoh attachment; a monitor given `--trust FILE`
# rejects (and counts) every sample of a listed platform whose signature is missing or wrong.


def signer(path: Path) -> Any:
    """(key expression, payload) → signature, with the Ed25519 private key in PEM at `path`."""
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
    from cryptography.hazmat.primitives.serialization import load_pem_private_key

    try:
        key = load_pem_private_key(read_text(path).encode(), password=None)
    except (ValueError, TypeError) as exc:
        raise DkError(f"{path}: not an unencrypted PEM private key ({exc})") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise DkError(
            f"{path}: not an Ed25519 key (make one with `openssl genpkey "
            f"-algorithm ed25519 -out {path.name}`)"
        )
    return lambda key_expr, payload: key.sign(key_expr.encode() + b"\n" + payload)


def trusted_keys(path: Path) -> dict[str, Any]:
    """Platform → Ed25519 public key, from a TOML file `platform2 = "keys/p2.pub.pem"` (a PEM
    file relative to it, or the PEM text itself)."""
    import tomllib

    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey
    from cryptography.hazmat.primitives.serialization import load_pem_public_key

    try:
        table = tomllib.loads(read_text(path))
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ParseError(f"not TOML ({str(exc)[:100]})", Span(str(path))) from None
    keys = {}
    for platform, value in table.items():
        if not isinstance(value, str):
            raise ParseError(f"{platform}: expected a PEM file or PEM text", Span(str(path)))
        pem = value if "-----BEGIN" in value else read_text(path.parent / value)
        try:
            key = load_pem_public_key(pem.encode())
        except (ValueError, TypeError) as exc:
            raise ParseError(
                f"{platform}: not a PEM public key ({str(exc)[:80]})", Span(str(path))
            ) from None
        if not isinstance(key, Ed25519PublicKey):
            raise ParseError(f"{platform}: not an Ed25519 public key", Span(str(path)))
        keys[platform] = key
    return keys


def verify(key: Any, key_expr: str, payload: bytes, signature: bytes | None) -> None:
    from cryptography.exceptions import InvalidSignature

    if signature is None:
        raise WireError(f"{key_expr}: unsigned sample from a platform that must sign", "unsigned")
    try:
        key.verify(signature, key_expr.encode() + b"\n" + payload)
    except InvalidSignature:
        raise WireError(f"{key_expr}: bad signature", "signature") from None
