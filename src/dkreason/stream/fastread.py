"""Read only the fields a stream request needs, straight from serialised messages.

A monitor reads a handful of fields per message (its id fields, its value, the header stamp),
so instead of deserialising whole messages it unpacks those fields at offsets computed from the
message definition: generated once per message type, with `struct`.  Supported up to the last
needed field: fixed-size primitives, strings, nested messages and fixed-size arrays of
primitives (CDR for ROS 2, with its alignment; the packed ROS 1 format).  A type with anything
else before a needed field (a sequence, an array of strings or messages) returns None and is
deserialised in full instead; so is a big-endian CDR message.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from .fields import path

_FORMAT = {"bool": ("?", 1), "int8": ("b", 1), "uint8": ("B", 1), "byte": ("B", 1),
           "char": ("B", 1), "int16": ("h", 2), "uint16": ("H", 2), "int32": ("i", 4),
           "uint32": ("I", 4), "float32": ("f", 4), "int64": ("q", 8), "uint64": ("Q", 8),
           "float64": ("d", 8)}

Extractor = Callable[[bytes], tuple[Any, ...] | None]


class _Unsupported(Exception):
    pass


def compile_extractor(fielddefs: Mapping[str, Any], msgtype: str, fields: Sequence[str],
                      ros1: bool, otherwise: Extractor | None = None) -> Extractor | None:
    """A function returning the values of `fields` (in order) from one serialised message,
    or None when the type's layout is not one it can read.  A message it cannot read (big
    endian) goes to `otherwise` (None without it), inside the one call."""
    wanted = {tuple(path(f)): n for n, f in enumerate(fields)}
    lines: list[str] = []
    try:
        _walk(fielddefs, msgtype, (), wanted, lines, ros1, finish=False)
    except _Unsupported:
        return None
    if wanted:
        return None  # some field is not in the type (the processor reports it)
    head = ["def extract(raw):"]
    if not ros1:
        head.append("    if raw[1] != 1:\n        return otherwise(raw)  # big-endian CDR")
    body = "\n".join([*head, f"    o = {0 if ros1 else 4}", *lines,
                      f"    return ({''.join(f'v{n}, ' for n in range(len(fields)))})"])
    scope: dict[str, Any] = {}
    import struct

    scope["unpack"] = struct.unpack_from
    scope["otherwise"] = otherwise or (lambda raw: None)
    exec(compile(body, f"<extract {msgtype}>", "exec"), scope)  # noqa: S102 - our own code
    extract: Extractor = scope["extract"]
    return extract


def _align(size: int, ros1: bool) -> str:
    return "" if ros1 or size == 1 else f"    o = ((o - 4 + {size - 1}) & {-size}) + 4\n"


def _under(key: tuple[Any, ...], prefix: tuple[Any, ...]) -> bool:
    return key[: len(prefix)] == prefix


def _walk(fielddefs: Mapping[str, Any], msgtype: str, prefix: tuple[Any, ...],
          wanted: dict[tuple[Any, ...], int], lines: list[str], ros1: bool,
          finish: bool) -> None:
    """Emit code reading the wanted fields of `msgtype`; stop early unless `finish` (the
    caller needs the offset after the whole message)."""
    if msgtype not in fielddefs:
        raise _Unsupported(msgtype)
    for name, (nodetype, spec) in fielddefs[msgtype][1]:
        if not finish and not any(_under(k, prefix) for k in wanted):
            return
        here = (*prefix, name)
        kind = int(nodetype)
        if kind == 1 and spec[0] == "string":
            lines.append(_align(4, ros1) + "    n = unpack('<I', raw, o)[0]\n    o += 4")
            if here in wanted:
                end = "o + n" if ros1 else "o + n - 1"
                lines.append(f"    v{wanted.pop(here)} = str(raw[o:{end}], 'utf-8')")
            lines.append("    o += n")
        elif kind == 1:
            if spec[0] not in _FORMAT:
                raise _Unsupported(spec[0])
            fmt, size = _FORMAT[spec[0]]
            code = _align(size, ros1)
            if here in wanted:
                code += f"    v{wanted.pop(here)} = unpack('<{fmt}', raw, o)[0]\n"
            lines.append(code + f"    o += {size}")
        elif kind == 2:
            after = finish or any(_under(k, prefix) and not _under(k, here) for k in wanted)
            _walk(fielddefs, spec, here, wanted, lines, ros1, after)
        elif kind == 3 and int(spec[0][0]) == 1 and spec[0][1][0] in _FORMAT:
            fmt, size = _FORMAT[spec[0][1][0]]
            code = _align(size, ros1)
            for key in [k for k in wanted if _under(k, here)]:
                if len(key) != len(here) + 1 or not isinstance(key[-1], int) or \
                        key[-1] >= spec[1]:
                    raise _Unsupported("array element")
                code += f"    v{wanted.pop(key)} = unpack('<{fmt}', raw, o + {key[-1] * size})[0]\n"
            lines.append(code + f"    o += {spec[1] * size}")
        else:
            raise _Unsupported(f"{msgtype}.{name}")
