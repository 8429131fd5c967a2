"""Compressed chunks of recordings, inflated within bounds checked before anything is allocated.

A chunk (of an MCAP file or a ROS 1 bag) says how many bytes it inflates to, and a damaged or
hostile file may say anything: 2 GB in a 69 KB zstd chunk, or a size its data inflates past.
So the size a chunk declares is held to two bounds before it is read: the bytes one input may
hold (`max_input()`, DKREASON_MAX_INPUT, 256 MB) and `max_ratio()` times the chunk's compressed
size (DKREASON_MAX_CHUNK_RATIO, 1,000: zstd reaches ~30,000 on zeros, real sensor data 2–50);
and no decompressor is let write more than that size.  Data that does not inflate as declared
gives what came out before it failed (`BadChunk.prefix`): the records in those bytes are good.
rosbags' own decompressors are replaced by these (`bound_rosbags`), so no path inflates
unbounded.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from typing import Any

from ..errors import DkError
from ..inputs.files import max_input
from .typestore import why

DEFAULT_MAX_RATIO = 1000
_STEP = 1 << 16  # bytes inflated at a time when looking for what came out before a failure


def max_ratio() -> int:
    """How many times its compressed size a chunk may inflate to: DKREASON_MAX_CHUNK_RATIO."""
    text = os.environ.get("DKREASON_MAX_CHUNK_RATIO", "").strip()
    if not text:
        return DEFAULT_MAX_RATIO
    if not text.isascii() or not text.isdigit() or len(text) > 15 or int(text) < 1:
        raise DkError(
            f"DKREASON_MAX_CHUNK_RATIO={os.environ['DKREASON_MAX_CHUNK_RATIO']!r}: expected a "
            f"whole number of at least 1"
        )
    return int(text)


class BadChunk(Exception):
    """Why a chunk does not inflate as it declares; `prefix`: the bytes it gave before."""

    def __init__(self, why: str, prefix: bytes = b"") -> None:
        super().__init__(why)
        self.prefix = prefix


class _Over(Exception):
    """The data inflates to more than it may."""


def _bound(compression: str, compressed: int) -> tuple[int, str]:
    """The bytes a chunk of `compressed` bytes may inflate to, and that bound in words."""
    limit, ratio = max_input(), max_ratio()
    if compression and ratio * compressed < limit:
        return ratio * compressed, (
            f"{ratio:,} times its {compressed:,} compressed bytes "
            f"(raise DKREASON_MAX_CHUNK_RATIO to read it)"
        )
    return limit, f"the {limit:,} one input may hold (raise DKREASON_MAX_INPUT to read it)"


def refusal(compression: str, size: int, compressed: int) -> str | None:
    """Why a chunk declaring `size` bytes from `compressed` is refused unread (None: it is
    within both bounds)."""
    limit, words = _bound(compression, compressed)
    return f"declares {size:,} bytes, more than {words}" if size > limit else None


def inflate(compression: str, data: bytes, size: int) -> bytes:
    """`data` inflated to exactly the `size` bytes it declares.  BadChunk before anything is
    allocated when `size` is over a bound, and when the data inflates to anything else (with
    what came out before the failure, at most `size` bytes)."""
    refused = refusal(compression, size, len(data))
    if refused is not None:
        raise BadChunk(refused)
    if compression and compression not in _INFLATE:  # MCAP's zstd, lz4; ROS 1's bz2, lz4
        raise BadChunk(f"has an unknown compression {compression!r}")
    if not compression:  # none (ROS 1's "none" is given as "")
        if len(data) != size:
            raise BadChunk(f"holds {len(data):,} bytes, not the {size:,} it declares", data[:size])
        return data
    try:
        out = _INFLATE[compression](data, size)
    except _Over:
        broken = f"inflates to more than the {size:,} bytes it declares"
    except Exception as exc:  # each decompressor raises its own kind for bad data
        broken = f"does not decompress ({why(exc)})"
    else:
        if len(out) == size:
            return out
        broken = f"inflates to {len(out):,} bytes, not the {size:,} it declares"
    raise BadChunk(broken, _prefix(compression, data, size))


def inflate_prefix(compression: str, data: bytes, size: int) -> tuple[bytes, str | None]:
    """What `inflate` gives, and None; or, when the chunk is refused or damaged, the bytes
    that came out before the failure (maybe none) and why."""
    try:
        return inflate(compression, data, size), None
    except BadChunk as bad:
        return bad.prefix, str(bad)


def inflate_within(compression: str, data: bytes) -> bytes:
    """`data` inflated for a reader that does not say what size it expects (rosbags' ROS 1
    chunks): to at most what the bounds allow a chunk of its compressed size."""
    limit, words = _bound(compression, len(data))
    try:
        return _INFLATE[compression](data, limit)
    except _Over:
        raise BadChunk(f"a chunk ({compression}) inflates to more than {words}") from None


def _zstd(data: bytes, size: int) -> bytes:
    import zstandard

    if zstandard.frame_content_size(data) > size:  # zstandard would allocate what the frame
        raise _Over  # says (-1: it does not say), whatever the limit
    return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)


def _stepwise(make: Callable[[], Any]) -> Callable[[bytes, int], bytes]:
    """Inflate with a decompressor that takes `max_length` (lz4's, bz2's): never more than
    `size` bytes (_Over past them), the whole of its data (it must end where the data does)."""

    def inflate(data: bytes, size: int) -> bytes:
        decompressor = make()
        out: bytes = decompressor.decompress(data, max_length=size + 1)
        if len(out) > size:
            raise _Over
        if not decompressor.eof:
            raise ValueError("its compressed data ends early")
        return out

    return inflate


def _lz4() -> Any:
    import lz4.frame

    return lz4.frame.LZ4FrameDecompressor()


def _bz2() -> Any:
    import bz2

    return bz2.BZ2Decompressor()


_INFLATE: dict[str, Callable[[bytes, int], bytes]] = {
    "zstd": _zstd,
    "lz4": _stepwise(_lz4),
    "bz2": _stepwise(_bz2),
}


def _prefix(compression: str, data: bytes, size: int) -> bytes:
    """What `data` inflates to before it fails, at most `size` bytes."""
    out = bytearray()
    try:
        if compression == "zstd":
            import zstandard

            reader = zstandard.ZstdDecompressor().stream_reader(data)
            while len(out) < size and (piece := reader.read(min(_STEP, size - len(out)))):
                out += piece
        else:
            decompressor = _lz4() if compression == "lz4" else _bz2()
            for at in range(0, len(data), _STEP):
                if len(out) >= size:
                    break
                out += decompressor.decompress(data[at : at + _STEP], max_length=size - len(out))
    except Exception:  # the failure itself: what came before it is the answer
        pass
    return bytes(out)


def bound_rosbags() -> None:
    """rosbags inflates chunks with no bound (a zstd frame's own size, lz4 and bz2 to the
    end): its decompressors become these, for the files it reads itself."""
    from rosbags.rosbag1 import reader as ros1
    from rosbags.rosbag2 import storage_mcap

    storage_mcap.DECOMPRESSORS.update({name: partial(inflate, name) for name in ("lz4", "zstd")})
    ros1.decompressors.update({name: partial(inflate_within, name) for name in ("lz4", "bz2")})
