"""The one door for user files: bounded reads, line streams, locked and atomic edits.

Every file a user names is read here, so every read has the same limits: only regular files
(a device, FIFO or directory is refused at once instead of blocking or growing without end),
at most `max_input()` bytes (DKREASON_MAX_INPUT, default 256 MB), lines of at most
`MAX_LINE` bytes.  Edits hold an advisory lock beside the file, keep its mode, write through
symlinks and never leave half a file or a stray temporary behind.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import stat
import sys
import tempfile
from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span, one_line

DEFAULT_MAX_INPUT = 256 * 1024 * 1024
MAX_LINE = 16 * 1024 * 1024  # bytes of one JSON line (a message or a state)
_UNITS = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3}


def max_input() -> int:
    """Bytes one input file may hold: DKREASON_MAX_INPUT (`300M`, `2G`, bytes) or 256 MB."""
    text = os.environ.get("DKREASON_MAX_INPUT", "").strip().upper().removesuffix("B")
    if not text:
        return DEFAULT_MAX_INPUT
    unit = text[-1] if text[-1] in _UNITS else ""
    number = text[: len(text) - len(unit)]
    if not number.isascii() or not number.isdigit() or len(number) > 15:
        raise DkError(
            f"DKREASON_MAX_INPUT={os.environ['DKREASON_MAX_INPUT']!r}: expected a "
            f"size such as 300M or 2G"
        )
    return int(number) * _UNITS[unit]


def shown(path: Path | str) -> str:
    """`path` for a one-line message: control characters escaped."""
    return one_line(str(path))


def regular(path: Path) -> os.stat_result:
    """`path`'s status, if it is a regular file; else one error line (no such file, a
    directory, a device, FIFO or socket, a name with a NUL byte)."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise DkError(f"{shown(path)}: no such file") from None
    except ValueError:  # an embedded NUL byte
        raise DkError(f"{shown(path)}: not a valid file name") from None
    except OSError as exc:
        raise DkError(f"{shown(path)}: cannot read ({exc.strerror})") from None
    if stat.S_ISDIR(info.st_mode):
        raise DkError(f"{shown(path)}: is a directory, expected a file")
    if not stat.S_ISREG(info.st_mode):
        raise DkError(f"{shown(path)}: not a regular file (a device, FIFO or socket is not read)")
    return info


def resolved(path: Path) -> Path:
    """`path` made absolute with its symlinks followed; a loop of symlinks is one error line
    (pathlib raises RuntimeError for it before Python 3.13, OSError after)."""
    try:
        return path.resolve()
    except (RuntimeError, OSError):
        raise DkError(f"{shown(path)}: cannot read (a loop of symbolic links)") from None


def _too_big(path: Path, limit: int) -> DkError:
    return DkError(
        f"{shown(path)}: larger than {limit} bytes (raise DKREASON_MAX_INPUT to read it)"
    )


def read_bytes(path: Path) -> bytes:
    limit = max_input()
    if regular(path).st_size > limit:
        raise _too_big(path, limit)
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise DkError(f"{shown(path)}: cannot read ({exc.strerror})") from None
    if len(data) > limit:
        raise _too_big(path, limit)
    return data


def decode(data: bytes, path: Path | str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DkError(f"{shown(path)}: not UTF-8 text (byte {exc.start})") from None


def read_text(path: Path) -> str:
    return decode(read_bytes(path), path)


def lines(path: Path, name: str) -> Iterator[tuple[int, bytes]]:
    """(number, line) of a file or of standard input (`-`), bounded per line, read as they
    come (a pipe is followed line by line).  A line longer than MAX_LINE is an error."""
    if str(path) == "-":
        handle = sys.stdin.buffer
    else:
        regular(path)
        try:
            handle = open(path, "rb")  # noqa: SIM115 - closed below, also when abandoned
        except OSError as exc:
            raise DkError(f"{shown(path)}: cannot read ({exc.strerror})") from None
    with (
        contextlib.closing(handle)
        if handle is not sys.stdin.buffer
        else contextlib.nullcontext(handle)
    ):
        n = 0
        while line := handle.readline(MAX_LINE + 1):
            n += 1
            if len(line) > MAX_LINE:
                raise DkError(f"{name}:{n}: line longer than {MAX_LINE} bytes")
            yield n, line


_EXACT, _FLOAT = json.JSONDecoder(parse_float=Decimal), json.JSONDecoder()


def json_value(data: bytes | str, where: Span, exact: bool = True) -> Any:
    """One JSON document (numbers with a fraction or exponent as exact decimals unless not
    `exact`); any failure — syntax, encoding, nesting, a number too long — is a ParseError."""
    try:  # json.loads, with its decoder made once, not per document
        text = (
            data
            if isinstance(data, str)
            else data.decode(
                "utf-8" if data[:1] == b"{" and data[1:2] != b"\0" else json.detect_encoding(data),
                "surrogatepass",
            )
        )  # an object in UTF-8 (what peers send) needs no sniffing
        if text.startswith("\ufeff"):
            raise json.JSONDecodeError("Unexpected UTF-8 BOM (decode using utf-8-sig)", text, 0)
        return (_EXACT if exact else _FLOAT).decode(text)
    except json.JSONDecodeError as exc:
        why, column = f"not JSON: {exc.msg}", exc.colno
    except UnicodeDecodeError as exc:
        why, column = "not UTF-8 text", exc.start + 1
    except RecursionError:
        why, column = "JSON nested too deeply", 0
    except ValueError as exc:  # an integer of more than 4300 digits
        why, column = f"not JSON ({str(exc).split(';')[0][:80]})", 0
    except ArithmeticError:  # decimal.InvalidOperation: an exponent too long for a Decimal
        why, column = "not JSON (a number out of range)", 0
    raise ParseError(why, Span(where.file, where.line, column if where.line else 0))


# ---- edits -------------------------------------------------------------------------------


@contextlib.contextmanager
def locked(path: Path) -> Iterator[Path]:
    """Hold an exclusive advisory lock for editing `path`; yield the real file to edit (a
    symlink's target).  Temporaries that a killed editor left are removed under the lock."""
    target = Path(os.path.realpath(path))
    lock = target.parent / f".{target.name}.lock"
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise DkError(f"{shown(lock)}: cannot create the lock file ({exc.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        for stale in target.parent.glob(f".{target.name}.*.tmp"):
            stale.unlink(missing_ok=True)
        yield target
    finally:
        os.close(fd)


def write_atomic(path: Path, data: bytes) -> None:
    """Replace `path` in one step so a crash never leaves half a file behind; the file keeps
    its mode (new files get the umask's).  A write that fails (a full disk, a read-only
    folder) is one error line, and `path` is as it was."""
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as out:
            out.write(data)
            out.flush()
            os.fchmod(out.fileno(), mode)
            os.fsync(out.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise DkError(f"{shown(path)}: cannot write ({exc.strerror}); left as it was") from None
        raise
