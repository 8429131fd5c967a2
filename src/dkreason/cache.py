"""Parsed knowledge kept between runs, keyed by the content it came from.

Parsing dominates a cold load (rdflib for the ontology, lark for the specs: ~80% at 10k
objects), and most runs read the very files the previous run read.  A platform's parsed model
is pickled under a key that hashes everything it depends on: the files' paths and bytes, and
the source of the code that turned them into the model (so a changed parser never serves a
stale model).  A changed file is a new key; an unreadable entry is ignored and rebuilt.

Where: `$DKREASON_CACHE`, else `$XDG_CACHE_HOME/dkreason`, else `~/.cache/dkreason`;
`DKREASON_CACHE=off` disables it.  It is kept under `$DKREASON_CACHE_MB` (default 512);
the entries used longest ago go first.  The cache is the user's own, like `__pycache__`: whoever
can write there can run code as that user, so it is created private (0700).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import re
import tempfile
from collections.abc import Callable, Iterable
from functools import cache
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

_ENTRY = re.compile(r"[a-z]+-[0-9a-f]{64}")  # what `key` names; lark's tables are its own


def folder() -> Path | None:
    """Where entries live, or None when caching is off."""
    setting = os.environ.get("DKREASON_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false"):
        return None
    if setting:
        return Path(setting)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dkreason"


def code_digest(package: Path) -> bytes:
    """A digest of a package's code and grammars, names included: any change to how a value
    is built is a new key, with no list of modules to keep (or forget) when code moves."""
    digest = hashlib.sha256()
    for path in sorted(p for p in package.rglob("*") if p.suffix in (".py", ".lark")):
        data = path.read_bytes()
        name = path.relative_to(package).as_posix().encode()
        digest.update(len(name).to_bytes(8, "little") + name + len(data).to_bytes(8, "little"))
        digest.update(data)
    return digest.digest()


@cache
def _code_stamp() -> bytes:
    return code_digest(Path(__file__).parent)


def lark_file(grammar: str) -> str | bool:
    """Where lark keeps the analysed `grammar` (lark checks the grammar's hash itself), or
    False when caching is off: building the LALR tables costs 30-40 ms a grammar."""
    where = folder()
    if where is None:
        return False
    with contextlib.suppress(OSError):
        where.mkdir(mode=0o700, parents=True, exist_ok=True)
        return str(where / f"{grammar}.lark-cache")
    return False


def key(kind: str, parts: Iterable[bytes | str]) -> str:
    """The entry name for a value of `kind` built from `parts` (paths, file contents)."""
    digest = hashlib.sha256(_code_stamp() + kind.encode())
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        digest.update(len(data).to_bytes(8, "little") + data)
    return f"{kind}-{digest.hexdigest()}"


def cached(
    kind: str,
    parts: Iterable[bytes | str],
    build: Callable[[], T],
    fresh: Callable[[T], bool] = lambda _: True,
) -> T:
    """The value built from `parts`: from the cache when an entry exists and is `fresh` (it
    may depend on more than `parts`: the files an ontology imports), else `build()`, stored
    for the next run.  Errors from `build` pass through and nothing is stored."""
    where = folder()
    if where is None:
        return build()
    entry = where / key(kind, parts)
    # missing, truncated, from another Python: rebuild
    with contextlib.suppress(Exception), open(entry, "rb") as handle:
        found: T = pickle.load(handle)
        if fresh(found):
            with contextlib.suppress(OSError):
                os.utime(entry)  # used now: the last to go when the folder is pruned
            return found
    value = build()
    _store(entry, value)
    prune(where)
    return value


def prune(where: Path, limit: int | None = None) -> None:
    """Keep the folder under `limit` bytes (`$DKREASON_CACHE_MB`, default 512 MB) by removing
    the entries used longest ago: every edit of a file makes a new entry, and a robot's disk
    is small.  Lark's grammar tables stay."""
    if limit is None:
        try:
            limit = int(os.environ.get("DKREASON_CACHE_MB", "512")) << 20
        except ValueError:
            limit = 512 << 20
    with contextlib.suppress(OSError):
        entries = []
        for path in where.iterdir():
            if _ENTRY.fullmatch(path.name):
                with contextlib.suppress(OSError):
                    info = path.stat()
                    entries.append((info.st_mtime, info.st_size, path))
        total = sum(size for _, size, _ in entries)
        for _, size, path in sorted(entries):
            if total <= limit:
                break
            with contextlib.suppress(OSError):
                path.unlink()
                total -= size


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def unchanged(files: Iterable[tuple[str, str]]) -> bool:
    """Whether every (path, digest) still holds: the file is there with the same bytes."""
    for path, known in files:
        try:
            with open(path, "rb") as handle:
                if digest(handle.read()) != known:
                    return False
        except OSError:
            return False
    return True


def _store(entry: Path, value: object) -> None:
    """Write atomically (a reader sees the old entry or the whole new one); a cache that
    cannot be written (read-only home, full disk) only costs the next run its parse."""
    with contextlib.suppress(OSError, pickle.PicklingError, RecursionError):
        entry.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=entry.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as handle:
                pickle.dump(value, handle, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, entry)
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
