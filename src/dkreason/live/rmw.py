"""What ROS 2 puts on Zenoh: rmw_zenoh's and zenoh-bridge-ros2dds' keys, tokens, attachments.

rmw_zenoh (ROS 2 Jazzy and later, `RMW_IMPLEMENTATION=rmw_zenoh_cpp`):

    data key      <domain>/<topic without outer slashes>/<DDS type>/<type hash>
                  0/robot1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_…
    token         @ros2_lv/<domain>/<session>/<node id>/<entity id>/<kind>/<enclave>/<namespace>
                  /<node>/<topic>/<DDS type>/<type hash>/<qos>   (names with `/` written `%`)
    attachment    int64 sequence number, int64 source time (ns since the epoch), both little
                  endian, a length byte (16) and the publisher's 16-byte gid (33 bytes); Jazzy's
                  first releases wrote each item behind its name (77 bytes): both are read

zenoh-bridge-ros2dds (any ROS 2 on DDS, bridged):

    data key      <topic without its leading slash> (the bridge's namespace included)
    token         @ros2_lv/<bridge id>/<kind>/<data key>/<ROS type>/<qos>  (`/` written `§`)

Payloads are CDR with its 4-byte encapsulation header in both.  Everything here is total on a
peer's input: a result, None for what is not a topic publisher, or a WireError.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from ..errors import WireError

CLOCK = "/clock"  # sim time (`use_sim_time`), as `ros2 bag play --clock` publishes it
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
ADMIN = "@ros2_lv"
TOKENS = f"{ADMIN}/**"
MAX_TOKEN = 4096  # characters of one token's key expression
NO_HASH = "TypeHashNotSupported"  # what Humble-era rmw_zenoh writes, and ours for custom types
# REP-2011 hashes of the types dkreason itself publishes (rosidl computes them at build time)
HASHES = {
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
}
QOS = "::,7:,:,:,,"  # rmw_zenoh's default profile (reliable, volatile, keep last 7)
BRIDGE_QOS = ":::"
_DDS = re.compile(r"^([A-Za-z_]\w*)::(msg|srv|action)::dds_::(\w+)_$")
_ROS = re.compile(r"^([A-Za-z_]\w*)/(msg|srv|action)/(\w+)$")
_NAME = re.compile(r"^/$|^(/[\w~{}]+)+$")  # a fully qualified ROS name
_LABELS = (b"sequence_number", b"source_timestamp", b"source_gid")
_HASH = re.compile(r"^\w+$")  # RIHS01_<hex>, TypeHashNotSupported: never a wildcard


@dataclass(frozen=True, slots=True)
class Publisher:
    """A ROS 2 publisher as its liveliness token announces it."""

    token: str  # the token's key expression: the publisher's identity
    topic: str  # fully qualified ROS name, `/robot1/odom`
    msgtype: str  # `nav_msgs/msg/Odometry`
    key: str  # the key expression its samples are put on
    node: str | None  # node name and namespace (rmw_zenoh; the bridge does not tell them)
    namespace: str | None
    domain: int | None  # ROS_DOMAIN_ID (rmw_zenoh)
    bridged: bool  # announced by zenoh-bridge-ros2dds
    type_hash: str | None = None  # REP-2011's hash of its definition (rmw_zenoh; NO_HASH: none)

    def describe(self) -> str:
        where = (
            f" by {_join(self.namespace, self.node)}"
            if self.node is not None
            else " through the bridge"
            if self.bridged
            else ""
        )
        return f"{self.topic} ({self.msgtype}){where}"


def ros_type(dds: str) -> str:
    """`std_msgs::msg::dds_::String_` → `std_msgs/msg/String`."""
    m = _DDS.match(dds)
    if m is None:
        raise WireError(f"not a ROS 2 type name: {dds[:80]!r}", "token")
    return f"{m.group(1)}/{m.group(2)}/{m.group(3)}"


def dds_type(ros: str) -> str:
    m = _ROS.match(ros)
    if m is None:
        raise WireError(f"not a ROS 2 type name: {ros[:80]!r}", "token")
    return f"{m.group(1)}::{m.group(2)}::dds_::{m.group(3)}_"


def _name(mangled: str, slash: str, what: str) -> str:
    name = mangled.replace(slash, "/")
    name = name if name.startswith("/") else "/" + name
    if not _NAME.match(name):
        raise WireError(f"{what} {name[:80]!r} is not a ROS name", "token")
    return name


def _join(namespace: str | None, node: str) -> str:
    return (namespace or "/").rstrip("/") + "/" + node


def parse_token(key: str) -> Publisher | None:
    """The publisher a token announces; None for any other ROS 2 entity (a node, a
    subscription, a service) or anything outside `@ros2_lv`."""
    if len(key) > MAX_TOKEN:
        raise WireError(f"a liveliness token of {len(key)} characters", "token")
    parts = key.split("/")
    if parts[0] != ADMIN or len(parts) < 3:
        return None
    if parts[2] in ("MP", "MS", "SS", "SC", "AS", "AC"):  # zenoh-bridge-ros2dds
        if parts[2] != "MP":
            return None
        if len(parts) != 6:
            raise WireError(f"bridge publisher token with {len(parts)} parts: {key[:120]}", "token")
        data_key = parts[3].replace("§", "/")
        topic = _name(data_key, "/", "topic")
        msgtype = parts[4].replace("§", "/")
        if not _ROS.match(msgtype):
            raise WireError(f"not a ROS 2 type name: {msgtype[:80]!r}", "token")
        return Publisher(key, topic, msgtype, data_key, None, None, None, True)
    if len(parts) < 9 or parts[5] not in ("NN", "MP", "MS", "SS", "SC"):
        raise WireError(f"not an rmw_zenoh or bridge token: {key[:120]}", "token")
    if parts[5] != "MP":
        return None
    if len(parts) != 13:
        raise WireError(f"rmw_zenoh publisher token with {len(parts)} parts: {key[:120]}", "token")
    if not parts[1].isdigit():
        raise WireError(f"domain {parts[1][:20]!r} is not a number: {key[:120]}", "token")
    domain = int(parts[1])
    namespace = _name(parts[7], "%", "namespace")
    topic = _name(parts[9], "%", "topic")
    msgtype = ros_type(parts[10])
    if not _HASH.match(parts[11]):
        raise WireError(f"type hash {parts[11][:80]!r} is not one: {key[:120]}", "token")
    data_key = f"{domain}/{topic.strip('/')}/{parts[10]}/{parts[11]}"
    return Publisher(key, topic, msgtype, data_key, parts[8], namespace, domain, False, parts[11])


def publisher_token(
    session: str,
    node_id: int,
    entity_id: int,
    namespace: str,
    node: str,
    topic: str,
    msgtype: str,
    domain: int = 0,
    type_hash: str | None = None,
) -> str:
    """rmw_zenoh's token for a publisher (what `Ros2Node` declares); `type_hash`: its
    definition's (default: the one known here, or none)."""
    return "/".join(
        (
            ADMIN,
            str(domain),
            session,
            str(node_id),
            str(entity_id),
            "MP",
            "%",
            _mangle(namespace),
            node,
            _mangle(topic),
            dds_type(msgtype),
            type_hash or HASHES.get(msgtype, NO_HASH),
            QOS,
        )
    )


def bridge_token(bridge: str, topic: str, msgtype: str) -> str:
    """zenoh-bridge-ros2dds' token for a publisher it routes from DDS."""
    return "/".join(
        (
            ADMIN,
            bridge,
            "MP",
            topic.strip("/").replace("/", "§"),
            msgtype.replace("/", "§"),
            BRIDGE_QOS,
        )
    )


def data_key(topic: str, msgtype: str, domain: int = 0, type_hash: str | None = None) -> str:
    hashed = type_hash or HASHES.get(msgtype, NO_HASH)
    return f"{domain}/{topic.strip('/')}/{dds_type(msgtype)}/{hashed}"


def _mangle(name: str) -> str:
    return name.replace("/", "%") if name not in ("", "/") else "%"


# ---- attachments --------------------------------------------------------------------------

_PLAIN = struct.Struct("<qqB16s")
PLAIN_SIZE = _PLAIN.size


def attachment(sequence: int, source_time: int, gid: bytes, labelled: bool = False) -> bytes:
    """rmw_zenoh's attachment: 33 bytes, or with `labelled` the 77 of Jazzy's first releases
    (whose subscribers refuse the other)."""
    if not labelled:
        return _PLAIN.pack(sequence, source_time, 16, gid)
    items = (struct.pack("<q", sequence), struct.pack("<q", source_time), b"\x10" + gid)
    return b"".join(
        bytes([len(label)]) + label + item for label, item in zip(_LABELS, items, strict=True)
    )


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source time in ns, gid) of an rmw_zenoh attachment, in either
    layout."""
    if len(data) == _PLAIN.size:
        sequence, source_time, length, gid = _PLAIN.unpack(data)
        if length == 16:
            return sequence, source_time, gid
    elif len(data) == 77:  # each item behind its ULEB-prefixed name
        at, values = 0, []
        for label, size in zip(_LABELS, (8, 8, 17), strict=True):
            if data[at] != len(label) or data[at + 1 : at + 1 + len(label)] != label:
                break
            at += 1 + len(label)
            values.append(data[at : at + size])
            at += size
        else:
            if values[2][0] == 16:
                return (
                    int.from_bytes(values[0], "little", signed=True),
                    int.from_bytes(values[1], "little", signed=True),
                    values[2][1:],
                )
    raise WireError(f"not an rmw_zenoh attachment ({len(data)} bytes)", "attachment")


def check_cdr(payload: bytes, limit: int) -> None:
    """A payload must be plain CDR (either byte order) within `limit` bytes."""
    if len(payload) > limit:
        raise WireError(f"{len(payload)} bytes, more than the {limit} allowed", "size")
    if len(payload) < 4 or payload[0] != 0 or payload[1] > 1:
        raise WireError(f"not CDR (header {payload[:4].hex() or 'missing'})", "cdr")
