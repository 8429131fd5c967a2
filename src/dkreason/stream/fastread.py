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
from operator import itemgetter
from typing import Any

from .fields import path

_FORMAT = {
    "bool": ("?", 1),
    "int8": ("b", 1),
    "uint8": ("B", 1),
    "byte": ("B", 1),
    "char": ("B", 1),
    "int16": ("h", 2),
    "uint16": ("H", 2),
    "int32": ("i", 4),
    "uint32": ("I", 4),
    "float32": ("f", 4),
    "int64": ("q", 8),
    "uint64": ("Q", 8),
    "float64": ("d", 8),
}

Extractor = Callable[[bytes], tuple[Any, ...] | None]


class _Unsupported(Exception):
    pass


def compile_extractor(
    fielddefs: Mapping[str, Any],
    msgtype: str,
    fields: Sequence[str],
    ros1: bool,
    otherwise: Extractor | None = None,
) -> Extractor | None:
    """A function returning the values of `fields` (in order) from one serialised message,
    or None when the type's layout is not one it can read.  A message it cannot read (big
    endian) goes to `otherwise` (None without it), inside the one call."""
    unique = list(dict.fromkeys(fields))
    if len(unique) < len(fields):  # a field asked twice (a feature's field is the stamp)
        once = compile_extractor(fielddefs, msgtype, unique, ros1, otherwise)
        if once is None:
            return None
        again = itemgetter(*(unique.index(f) for f in fields))
        return lambda raw: None if (got := once(raw)) is None else again(got)
    wanted = {tuple(path(f)): n for n, f in enumerate(fields)}
    code = _Code(ros1)
    try:
        _walk(fielddefs, msgtype, (), wanted, code, finish=False)
    except _Unsupported:
        return None
    if wanted:
        return None  # some field is not in the type (the processor reports it)
    import struct

    scope: dict[str, Any] = {
        "unpack": struct.unpack_from,
        "otherwise": otherwise or (lambda raw: None),
    }
    head = "" if ros1 else "    if raw[1] != 1:\n        return otherwise(raw)  # big-endian CDR\n"
    body = code.body(len(fields), scope)
    exec(
        compile(f"def extract(raw):\n{head}{body}", f"<extract {msgtype}>", "exec"), scope
    )  # our own code
    extract: Extractor = scope["extract"]
    return extract


class _Code:
    """The reading code of one message type.  While no string has been passed, every offset
    is known when the code is made: the fields there are read by one `struct` call; after a
    string, offsets are computed as the message is read."""

    def __init__(self, ros1: bool) -> None:
        self.ros1 = ros1
        self.at: int | None = 0 if ros1 else 4  # the offset, while it is known
        self.fixed: list[tuple[int, str, int]] = []  # (offset, format, value number)
        self.lines: list[str] = []  # after the first string

    def _align(self, size: int) -> str:
        if self.ros1 or size == 1:
            return ""
        if self.at is not None:
            self.at = ((self.at - 4 + size - 1) & -size) + 4
            return ""
        return f"    o = ((o - 4 + {size - 1}) & {-size}) + 4\n"

    def primitive(
        self, fmt: str, size: int, values: Sequence[tuple[int, int]] = (), count: int = 1
    ) -> None:
        """`count` primitives of one format; `values`: (element, value number) to read."""
        code = self._align(size)
        for element, n in values:
            if self.at is not None:
                self.fixed.append((self.at + element * size, fmt, n))
            else:
                code += f"    v{n} = unpack('<{fmt}', raw, o + {element * size})[0]\n"
        if self.at is not None:
            self.at += count * size
        else:
            self.lines.append(code + f"    o += {count * size}")

    def string(self, n: int | None) -> None:
        if self.at is not None:
            self.lines.append(f"    o = {self.at}")
            self.at = None
        self.lines.append(self._align(4) + "    n = unpack('<I', raw, o)[0]\n    o += 4")
        if n is not None:
            end = "o + n" if self.ros1 else "o + n - 1"
            self.lines.append(f"    v{n} = str(raw[o:{end}], 'utf-8')")
        self.lines.append("    o += n")

    def body(self, count: int, scope: dict[str, Any]) -> str:
        """The function's body, returning the `count` values in order."""
        import struct

        layout, end = "<", 0
        for offset, fmt, _ in sorted(self.fixed):
            layout += "x" * (offset - end) + fmt
            end = offset + struct.calcsize("<" + fmt)
        scope["fixed"] = struct.Struct(layout).unpack_from
        order = [n for _, _, n in sorted(self.fixed)]
        if order == list(range(count)):  # every value, in order, at known offsets
            return "    return fixed(raw)\n"
        lines = [f"    {''.join(f'v{n}, ' for n in order)}= fixed(raw)"] if order else []
        return "\n".join(
            [*lines, *self.lines, f"    return ({''.join(f'v{n}, ' for n in range(count))})\n"]
        )


def _under(key: tuple[Any, ...], prefix: tuple[Any, ...]) -> bool:
    return key[: len(prefix)] == prefix


def _walk(
    fielddefs: Mapping[str, Any],
    msgtype: str,
    prefix: tuple[Any, ...],
    wanted: dict[tuple[Any, ...], int],
    code: _Code,
    finish: bool,
) -> None:
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
            code.string(wanted.pop(here) if here in wanted else None)
        elif kind == 1:
            if spec[0] not in _FORMAT:
                raise _Unsupported(spec[0])
            code.primitive(*_FORMAT[spec[0]], [(0, wanted.pop(here))] if here in wanted else [])
        elif kind == 2:
            after = finish or any(_under(k, prefix) and not _under(k, here) for k in wanted)
            _walk(fielddefs, spec, here, wanted, code, after)
        elif kind == 3 and int(spec[0][0]) == 1 and spec[0][1][0] in _FORMAT:
            elements = []
            for key in [k for k in wanted if _under(k, here)]:
                if len(key) != len(here) + 1 or not isinstance(key[-1], int) or key[-1] >= spec[1]:
                    raise _Unsupported("array element")
                elements.append((key[-1], wanted.pop(key)))
            code.primitive(*_FORMAT[spec[0][1][0]], elements, count=spec[1])
        else:
            raise _Unsupported(f"{msgtype}.{name}")
