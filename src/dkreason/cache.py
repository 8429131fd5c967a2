"""Parsed knowledge kept between runs, keyed by the content it came from, believed only once
it is proven to be ours.

Parsing dominates a cold load (rdflib for the ontology, lark for the specs: ~80% at 10k
objects), and most runs read the very files the previous run read.  A platform's parsed model
is pickled under a key that hashes everything it depends on: the files' paths and bytes, and
the source of the code that turned them into the model (so a changed parser never serves a
stale model).  A changed file is a new key.

Unpickling runs whatever a pickle names, so a cache is code.  No entry is unpickled before its
HMAC-SHA256 (over the entry's name and bytes) is checked with the user's own key, kept outside
the cache folder (`$XDG_STATE_HOME/dkreason/cache-key`, else `~/.local/state/...`, mode 0600):
an entry planted by someone else, renamed, truncated or with one bit flipped is rebuilt, the
same answer as no cache.  The folder is used only if it is the user's own and nobody else may
write in it (else one warning, and no cache); entries are read without following symlinks and
written to a fresh temporary that replaces the entry (atomic; a planted symlink is replaced,
never written through).

Where: `$DKREASON_CACHE`, else `$XDG_CACHE_HOME/dkreason`, else `~/.cache/dkreason`;
`DKREASON_CACHE=off` disables it.  It is kept under `$DKREASON_CACHE_MB` (default 512);
the entries used longest ago go first.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import logging
import os
import pickle
import re
import stat
import tempfile
from collections.abc import Callable, Iterable
from functools import cache
from pathlib import Path
from typing import IO, Any, TypeVar

from .errors import DkError
from .inputs.files import read_bytes

T = TypeVar("T")

log = logging.getLogger("dkreason.cache")
_ENTRY = re.compile(r"[a-z]+-[0-9a-f]{64}")  # what `key` names
_MAGIC = b"dkreason cache 1\n"  # then the HMAC, then the pickle
_MAC = hashlib.sha256().digest_size
_KEY_BYTES = 32
_MISSING = object()
_warned: set[str] = set()


def folder() -> Path | None:
    """Where entries live, or None when caching is off (turned off, a folder that cannot be
    made, or one that is not the user's alone)."""
    setting = os.environ.get("DKREASON_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false"):
        return None
    if setting:
        where = Path(setting)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        where = Path(base) / "dkreason"
    return where if _private(where, "cache folder") else None


def _private(where: Path, what: str) -> bool:
    """Whether `where` (made 0700 if missing) is a folder of the user's that no one else may
    write in; a folder that cannot be made (a read-only home) only costs the next run its parse,
    one that others control is a warning, once."""
    try:
        if not os.path.isdir(where):
            where.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = os.stat(where)
    except (OSError, ValueError):
        return False
    me = os.geteuid()
    why = (
        "not a folder"
        if not stat.S_ISDIR(info.st_mode)
        else f"owned by user {info.st_uid}, not {me}"
        if info.st_uid != me
        else f"writable by others (mode {stat.S_IMODE(info.st_mode):o})"
        if info.st_mode & 0o022
        else None
    )
    if why is not None:
        _warn(f"{what} {where}: {why}; not used, parsed knowledge is not cached")
    return why is None


def _warn(message: str) -> None:
    if message not in _warned:
        _warned.add(message)
        log.warning("warning: %s", message)


def signing_key() -> bytes | None:
    """The user's key that signs entries, made on first use; None when it cannot be made or is
    not the user's alone (then nothing is cached)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state"
    )
    return _key(Path(base) / "dkreason" / "cache-key")


@cache  # read once a process
def _key(path: Path) -> bytes | None:
    if not _private(path.parent, "cache key folder"):
        return None
    for _ in range(2):
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except FileNotFoundError:
            _make_key(path)
            continue
        except OSError as exc:
            _warn(f"cache key {path}: cannot read ({exc.strerror}); nothing is cached")
            return None
        with os.fdopen(fd, "rb") as handle:
            info = os.fstat(fd)
            data = handle.read(_KEY_BYTES + 1) if stat.S_ISREG(info.st_mode) else b""
        if info.st_uid != os.geteuid() or info.st_mode & 0o077 or len(data) != _KEY_BYTES:
            _warn(f"cache key {path}: not a private key of this user's; nothing is cached")
            return None
        return data
    return None


def _make_key(path: Path) -> None:
    """Write a new random key beside `path`, then link it into place: a concurrent run that
    made one first keeps its own, and no reader ever sees half a key."""
    with contextlib.suppress(OSError):
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".cache-key-")
        try:
            with os.fdopen(fd, "wb") as out:
                out.write(os.urandom(_KEY_BYTES))
                out.flush()
                os.fsync(out.fileno())
            with contextlib.suppress(FileExistsError):
                os.link(tmp, path)
        finally:
            os.unlink(tmp)


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
    """The value built from `parts`: from the cache when an entry exists, is proven ours and is
    `fresh` (it may depend on more than `parts`: the files an ontology imports), else `build()`,
    stored for the next run.  Errors from `build` pass through and nothing is stored."""
    where = folder()
    secret = signing_key() if where is not None else None
    if where is None or secret is None:
        return build()
    entry = where / key(kind, parts)
    found = _load(entry, secret)
    if found is not _MISSING and fresh(found):
        return found  # type: ignore[no-any-return]  # signed by us: a T, as stored
    value = build()
    _store(entry, value, secret)
    prune(where)
    return value


def _signer(secret: bytes, name: str) -> Any:
    return hmac.new(secret, name.encode() + b"\0", "sha256")


def _load(entry: Path, secret: bytes) -> Any:
    """The value in `entry`, or _MISSING: not there, not a regular file (a symlink is not
    followed, a FIFO not waited on), not signed with `secret` under this name, or unreadable.
    Read whole: its pickle is a fraction of the objects it makes."""
    try:
        fd = os.open(entry, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return _MISSING
    with os.fdopen(fd, "rb") as handle:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return _MISSING
        data = memoryview(handle.read())
        with contextlib.suppress(OSError):
            os.utime(fd)  # used now: the last to go when the folder is pruned
    start = len(_MAGIC) + _MAC
    mac = _signer(secret, entry.name)
    mac.update(data[start:])
    if data[: len(_MAGIC)] != _MAGIC or not hmac.compare_digest(
        data[len(_MAGIC) : start], mac.digest()
    ):
        return _MISSING
    try:  # signed by us, so made by this code: only a change of Python can fail here
        return pickle.loads(data[start:])
    except Exception:
        return _MISSING


class _Signed:
    """A file that signs what is written to it (pickle writes the entry in pieces, so it is
    never held twice in memory)."""

    def __init__(self, out: IO[bytes], mac: Any) -> None:
        self.out, self.mac = out, mac

    def write(self, data: bytes) -> int:
        self.mac.update(data)
        return self.out.write(data)


def _store(entry: Path, value: object, secret: bytes) -> None:
    """Write a fresh temporary, sign it, then rename it over the entry (a reader sees the old
    entry or the whole new one; a symlink at the entry's name is replaced, not followed); a
    cache that cannot be written (full disk) only costs the next run its parse."""
    with contextlib.suppress(OSError, pickle.PicklingError, RecursionError):
        fd, tmp = tempfile.mkstemp(dir=entry.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as out:
                out.write(_MAGIC + bytes(_MAC))
                signed = _Signed(out, _signer(secret, entry.name))
                pickle.dump(value, signed, protocol=pickle.HIGHEST_PROTOCOL)
                out.seek(len(_MAGIC))
                out.write(signed.mac.digest())
            os.replace(tmp, entry)
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


def prune(where: Path, limit: int | None = None) -> None:
    """Keep the folder under `limit` bytes (`$DKREASON_CACHE_MB`, default 512 MB) by removing
    the entries used longest ago: every edit of a file makes a new entry, and a robot's disk
    is small."""
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
                    info = path.lstat()
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


def unchanged(files: Iterable[tuple[str, str | None]]) -> bool:
    """Whether every (path, digest) still holds: the file has the same bytes, read through the
    input door (a FIFO or device is a change, never a wait), or, digest None, is still absent
    (a catalog that appears changes what an ontology imports)."""
    for path, known in files:
        if known is None:
            if os.path.lexists(path):
                return False
            continue
        try:
            if digest(read_bytes(Path(path))) != known:
                return False
        except DkError:
            return False
    return True
