"""Message fields as the specs write them (`msg.alt`, `msg.pose.position.z`, `msg.ids[1]`):
compiled once to accessors, and checked against message definitions before replay."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..errors import DkError

_PART = re.compile(r"\.([A-Za-z_]\w*)|\[(\d+)\]")


def path(field: str) -> list[str | int]:
    if not field.startswith("msg"):
        raise DkError(f"field {field!r} must start with msg")
    parts: list[str | int] = []
    rest = field[3:]
    while rest:
        m = _PART.match(rest)
        if m is None:
            raise DkError(f"field {field!r}: cannot read {rest!r}")
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        rest = rest[m.end() :]
    return parts


def accessor(field: str, dicts: bool) -> Callable[[Any], Any]:
    """A function reading `field` from a message object (rosbags) or a dict (JSON lines)."""
    code = "m"
    for p in path(field):
        code += f"[{p}]" if isinstance(p, int) else (f"[{p!r}]" if dicts else f".{p}")
    scope: dict[str, Any] = {}
    exec(f"def get(m):\n    return {code}\n", scope)
    get: Callable[[Any], Any] = scope["get"]
    return get


def check(fielddefs: dict[str, Any], msgtype: str, field: str) -> str | None:
    """Why `field` cannot be read from messages of `msgtype`, or None if it can."""
    found = _resolve(fielddefs, msgtype, field)
    return found if isinstance(found, str) else None


def kind(fielddefs: dict[str, Any], msgtype: str, field: str) -> tuple[str, str] | None:
    """(number, bool, string, message or array; the ROS type) of `field`, None if unknown."""
    found = _resolve(fielddefs, msgtype, field)
    if isinstance(found, str):
        return None
    category, what = found
    if category == "name":
        return "message", str(what)
    if category == "array":
        return "array", "an array"
    name = str(what[0] if isinstance(what, tuple) else what)
    return (
        "bool" if name == "bool" else "string" if name in ("string", "wstring") else "number"
    ), name


def _resolve(fielddefs: dict[str, Any], msgtype: str, field: str) -> tuple[str, Any] | str:
    """The descriptor `field` reaches in messages of `msgtype`, or why it reaches none."""
    current: Any = ("name", msgtype)
    walked = "msg"
    for p in path(field):
        kind_, what = current
        if isinstance(p, int):
            if kind_ != "array":
                return f"{walked} is not an array"
            current = what
        else:
            if kind_ != "name" or what not in fielddefs:
                return f"{walked} has no fields"
            fields = dict(fielddefs[what][1])
            if p not in fields:
                known = ", ".join(fields) or "none"
                return f"{what} has no field {p!r} (fields: {known})"
            current = _desc(fields[p])
        walked += f"[{p}]" if isinstance(p, int) else f".{p}"
    return current  # type: ignore[no-any-return]


def _desc(desc: Any) -> tuple[str, Any]:
    nodetype, spec = desc
    value = int(nodetype)
    if value == 2:  # NAME
        return ("name", spec)
    if value in (3, 4):  # ARRAY, SEQUENCE
        return ("array", _desc(spec[0]))
    return ("base", spec)


@dataclass(frozen=True, slots=True)
class FieldPath:
    """A field a spec can read (`msg.pose.position.z`): a number, bool or string, with its ROS
    type; an array's elements are written with their index (`msg.ranges[i]`, a sequence of any
    length; `msg.covariance[0..35]`, fixed size), which a spec gives as a number."""

    path: str
    ros_type: str

    @property
    def kind(self) -> str:
        """number, bool or string: how a formula may use it."""
        return (
            "bool"
            if self.ros_type == "bool"
            else "string"
            if self.ros_type in ("string", "wstring")
            else "number"
        )

    def to_json(self) -> dict[str, str]:
        return {"field": self.path, "type": self.ros_type, "kind": self.kind}


DEPTH = 12  # nested messages followed (a definition cannot recurse, but may be deep)


def paths(fielddefs: dict[str, Any], msgtype: str) -> list[FieldPath]:
    """Every field path of `msgtype` a spec can read, in definition order."""
    out: list[FieldPath] = []

    def walk(desc: tuple[str, Any], at: str, depth: int) -> None:
        kind_, what = desc
        if kind_ == "base":
            out.append(FieldPath(at, str(what[0] if isinstance(what, tuple) else what)))
        elif kind_ == "array":
            walk(what[0], at + what[1], depth)
        elif depth < DEPTH and what in fielddefs:
            for name, field in fielddefs[what][1]:
                walk(_indexed(field), f"{at}.{name}", depth + 1)

    walk(("name", msgtype), "msg", 0)
    return out


def _indexed(desc: Any) -> tuple[str, Any]:
    """A field's descriptor, an array's with the index it is written with."""
    nodetype, spec = desc
    if int(nodetype) in (3, 4):  # ARRAY (fixed size), SEQUENCE
        size = int(spec[1])
        index = f"[0..{size - 1}]" if int(nodetype) == 3 and size else "[i]"
        return ("array", (_indexed(spec[0]), index))
    return _desc(desc)
