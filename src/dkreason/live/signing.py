"""Signed samples: Ed25519 over the key expression and the payload.

A node started with `--sign KEY` puts each topic payload with a 64-byte signature of
`key expression + "\\n" + payload` as the Zenoh attachment; a monitor given `--trust FILE`
rejects (and counts) every sample of a listed platform whose signature is missing or wrong.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span, WireError
from ..inputs.files import read_text


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
