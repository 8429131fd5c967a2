"""Signed samples and knowledge replies: Ed25519, bound to the node's run and to the question.

A node started with `--sign KEY` draws a random session nonce at start.  It puts each topic
payload with the attachment `nonce + signature` (80 bytes), the signature over
`"sample\\n" + nonce + key expression + "\\n" + payload`; it answers each knowledge query
(ontology, specs, objects) with the attachment `nonce + signature` over
`"reply\\n" + challenge + nonce + key expression + "\\n" + payload`, where the challenge is the
random bytes the monitor attached to its query.  A monitor given `--trust FILE`:

- refuses to start unless every key in FILE names a platform of its config (and FILE names
  one at least): a misspelt name would leave that platform unsigned, so it fails closed;
- takes a listed platform's knowledge only from a reply signed for its own challenge (a reply
  recorded earlier answers another challenge), and learns the node's nonce from it;
- rejects and counts every sample of a listed platform that is unsigned, badly signed, or
  signed under another nonce than the node's current one (a sample replayed from another
  run: kind `replay`).

The prefixes keep a sample's signature from passing as a reply's and the reverse.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import DkError, ParseError, Span, WireError
from ..inputs.files import read_text

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

NONCE = 16  # bytes of a session nonce and of a query's challenge
SIGNATURE = 64  # bytes of an Ed25519 signature
ATTACHMENT = NONCE + SIGNATURE


@dataclass(frozen=True, slots=True)
class Signer:
    """A node's private key and the nonce of its run."""

    key: Ed25519PrivateKey
    nonce: bytes

    def sample(self, key_expr: str, payload: bytes) -> bytes:
        """The attachment of a topic payload."""
        return self.nonce + self.key.sign(_sample(self.nonce, key_expr, payload))

    def reply(self, challenge: bytes, key_expr: str, payload: bytes) -> bytes:
        """The attachment of a knowledge reply to a query that attached `challenge`."""
        return self.nonce + self.key.sign(_reply(challenge, self.nonce, key_expr, payload))


def _sample(nonce: bytes, key_expr: str, payload: bytes) -> bytes:
    return b"sample\n" + nonce + key_expr.encode() + b"\n" + payload


def _reply(challenge: bytes, nonce: bytes, key_expr: str, payload: bytes) -> bytes:
    return b"reply\n" + challenge + nonce + key_expr.encode() + b"\n" + payload


def signer(path: Path) -> Signer:
    """The Ed25519 private key in PEM at `path`, with a fresh session nonce."""
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
    return Signer(key, os.urandom(NONCE))


def trusted_keys(path: Path, platforms: Collection[str]) -> dict[str, Any]:
    """Platform → Ed25519 public key, from a TOML file `platform2 = "keys/p2.pub.pem"` (a PEM
    file relative to it, or the PEM text itself); every name one of `platforms`."""
    import tomllib

    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey
    from cryptography.hazmat.primitives.serialization import load_pem_public_key

    try:
        table = tomllib.loads(read_text(path))
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ParseError(f"not TOML ({str(exc)[:100]})", Span(str(path))) from None
    check_trust(table, platforms, str(path))
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


def check_trust(keys: Collection[str], platforms: Collection[str], where: str) -> None:
    """Fail closed: trust that names no platform, or one the config does not name (which
    would leave the meant platform unsigned), is an error."""
    if not keys:
        raise DkError(f"{where}: names no platform's key, so nothing would be checked")
    for name in sorted(keys):
        if name not in platforms:
            near = difflib.get_close_matches(name, list(platforms), 1) or [
                p for p in platforms if p.lower() == name.lower()
            ]
            hint = f" (did you mean {near[0]}?)" if near else ""
            raise DkError(
                f"{where}: {name!r} is not a platform of the config{hint}; "
                f"platforms: {', '.join(sorted(platforms))}"
            )


def verify_sample(
    key: Any, nonce: bytes | None, key_expr: str, payload: bytes, attachment: bytes | None
) -> None:
    """A listed platform's sample: signed by its key, under `nonce` (its node's current run)."""
    from cryptography.exceptions import InvalidSignature

    if attachment is None:
        raise WireError(f"{key_expr}: unsigned sample from a platform that must sign", "unsigned")
    if len(attachment) != ATTACHMENT:
        raise WireError(f"{key_expr}: bad signature ({len(attachment)} bytes)", "signature")
    carried = attachment[:NONCE]
    try:
        key.verify(attachment[NONCE:], _sample(carried, key_expr, payload))
    except InvalidSignature:
        raise WireError(f"{key_expr}: bad signature", "signature") from None
    if carried != nonce:
        raise WireError(
            f"{key_expr}: a signed sample of another run of the node (replayed)", "replay"
        )


def verify_reply(
    key: Any, challenge: bytes, key_expr: str, payload: bytes, attachment: bytes | None
) -> bytes:
    """A listed platform's knowledge reply, signed for `challenge`: the node's nonce."""
    from cryptography.exceptions import InvalidSignature

    if attachment is None or len(attachment) != ATTACHMENT:
        raise WireError(f"{key_expr}: unsigned reply from a platform that must sign", "unsigned")
    nonce = attachment[:NONCE]
    try:
        key.verify(attachment[NONCE:], _reply(challenge, nonce, key_expr, payload))
    except InvalidSignature:
        raise WireError(f"{key_expr}: bad signature on the reply", "signature") from None
    return nonce
