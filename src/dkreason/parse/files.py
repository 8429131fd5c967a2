"""Reading and atomically writing user files, with errors that name the file."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..errors import DkError


def read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise DkError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise DkError(f"{path}: is a directory, expected a file") from None
    except OSError as exc:
        raise DkError(f"{path}: cannot read ({exc.strerror})") from None


def read_text(path: Path) -> str:
    data = read_bytes(path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DkError(f"{path}: not UTF-8 text (byte {exc.start})") from None


def write_atomic(path: Path, text: str) -> None:
    """Replace `path` in one step so a crash never leaves half a file behind."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as out:
            out.write(text)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
