"""Write ROS recordings (for examples, tests and converting data): ROS 1 `.bag`, ROS 2 bag
folders with sqlite3 or MCAP storage, or a bare `.mcap` file, with message types given as
`.msg` text and messages as dicts (`header` stamps as seconds)."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

Format = Literal["ros1", "sqlite3", "mcap", "bare-mcap"]
Row = tuple[str, str, int, Mapping[str, Any]]  # topic, msgtype, record time (ns), fields


def write_recording(
    path: Path, fmt: Format, types: Mapping[str, str], messages: Iterable[Row]
) -> None:
    """Write `messages` (record-time order) to `path`; types: msgtype → .msg definition."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)
    for name, text in types.items():
        store.register(get_types_from_msg(text, name))
    rows = sorted(messages, key=lambda r: r[2])
    if fmt == "bare-mcap":
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "bag"
            write_recording(folder, "mcap", types, rows)
            (mcap,) = folder.glob("*.mcap")
            shutil.move(str(mcap), path)
        return
    if fmt == "ros1":
        from rosbags.rosbag1 import Writer as Writer1

        writer: Any = Writer1(path)
        serialize = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
        serialize = store.serialize_cdr
    with writer:
        connections: dict[str, Any] = {}
        for topic, msgtype, t_ns, fields in rows:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(
                connections[topic], t_ns, serialize(_build(store, msgtype, fields), msgtype)
            )


def _build(store: Any, msgtype: str, fields: Mapping[str, Any]) -> Any:
    """A message object from a dict; nested types from nested dicts, header stamps from s."""
    cls = store.types[msgtype]
    defs = dict(store.fielddefs[msgtype][1])
    values = {}
    for name, (nodetype, spec) in defs.items():
        value = fields.get(name)
        if int(nodetype) == 2:  # a nested message
            if spec.endswith("Header"):
                given = value or {}
                stamp = float(given.get("stamp", 0))
                sec = int(stamp)
                value = {
                    "stamp": {"sec": sec, "nanosec": round((stamp - sec) * 1e9)},
                    "frame_id": given.get("frame_id", ""),
                    **({"seq": 0} if "seq" in dict(store.fielddefs[spec][1]) else {}),
                }
            value = _build(store, spec, value or {})
        elif value is None:
            value = _zero(spec)
        values[name] = value
    return cls(**values)


def _zero(spec: Any) -> Any:
    kind = spec[0] if isinstance(spec, tuple) else spec
    if kind == "bool":
        return False
    if kind == "string":
        return ""
    return 0.0 if str(kind).startswith("float") else 0
