"""ROS message definitions: rosbags' standard typestores, `.msg` files read through the
input door, and readers of a message's wanted fields (from bytes where the layout allows)."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import DkError
from ..inputs.files import read_text
from . import fields


def store_name(ros1: bool, name: str | None) -> str:
    return name or ("ros1_noetic" if ros1 else "ros2_humble")


def load_typestore(given: dict[str, Any], ros1: bool, name: str | None = None) -> Any:
    """rosbags' standard definitions of `name` (default by the recording's kind), with the
    `given` types added or in place of their namesakes."""
    from rosbags.typesys import Stores, get_typestore

    return with_definitions(get_typestore(Stores(store_name(ros1, name))), given)


def with_definitions(store: Any, given: dict[str, Any]) -> Any:
    """`store` with the `given` definitions added, each in place of a namesake (rosbags' own
    register refuses a second definition of a type, so that case is a new store)."""
    from rosbags.typesys import Stores, get_typestore

    if all(
        store.fielddefs.get(name, definition) == definition for name, definition in given.items()
    ):
        store.register(given)
        return store
    fresh = get_typestore(Stores.EMPTY)
    fresh.register(store.fielddefs | given)
    return fresh


_TYPE = re.compile(r"[a-z][a-z0-9_]*/msg/[A-Z][A-Za-z0-9]*")  # as rosbags writes a message type
_FIELD = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def msg_types(msg_files: Sequence[Path]) -> dict[str, Any]:
    """The types `pkg/msg/Name.msg` files define, in rosbags' form.  rosbags reads most text
    as some definition ("hello world": a field `world` of type `hello`), so each field's name
    and type must also be ones ROS allows: a file of anything else is refused, not used."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for path in msg_files:
        if path.suffix != ".msg" or path.parent.name != "msg":
            raise DkError(f"{path}: expected a message definition pkg/msg/Name.msg")
        name = f"{path.parent.parent.name}/msg/{path.stem}"
        text = read_text(path)
        try:
            found = get_types_from_msg(text, name)
        except Exception as exc:
            raise DkError(f"{path}: not a message definition ({why(exc)})") from None
        for definition in found.values():
            odd = _odd_field(definition)
            if odd is not None:
                raise DkError(f"{path}: not a message definition ({odd})")
        types.update(found)
    return types


def _odd_field(definition: Any) -> str | None:
    """What in a parsed definition no ROS message definition has (None: nothing)."""
    for field, (nodetype, spec) in definition[1]:
        if not _FIELD.fullmatch(field):
            return f"{field!r} is not a field name"
        while int(nodetype) in (3, 4):  # an array or a sequence: of its elements
            nodetype, spec = spec[0]
        if int(nodetype) == 2 and not _TYPE.fullmatch(spec):
            return f"field {field} has type {spec.rpartition('/')[2]!r}, not a message type name"
    return None


def why(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:200]


def plain(value: Any) -> Any:
    """A deserialised ROS message as JSON-ready dicts, lists and numbers."""
    if hasattr(value, "__dataclass_fields__"):
        return {
            k: plain(getattr(value, k))
            for k in value.__dataclass_fields__
            if not k.startswith("__")
        }
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def ros_reader(
    fielddefs: Any, msgtype: str, wanted: list[str], ros1: bool, deserialize: Any
) -> tuple[Any, bool]:
    """(raw message → values of `wanted`, then the header stamp if it has one; stamped?)."""
    from .fastread import compile_extractor

    stamped = fields.check(fielddefs, msgtype, "msg.header.stamp.sec") is None
    names = [*wanted, *(["msg.header.stamp.sec", "msg.header.stamp.nanosec"] if stamped else [])]
    getters = [fields.accessor(f, dicts=False) for f in names]

    def slow(raw: Any) -> tuple[Any, ...]:
        msg = deserialize(raw, msgtype)
        return tuple(plain(get(msg)) for get in getters)

    return compile_extractor(fielddefs, msgtype, names, ros1, slow) or slow, stamped
