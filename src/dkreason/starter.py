"""`dkreason init`: a starter model from a recording, so a first formula over one's own robot
needs no OWL written by hand.

The recording's topics (all, or those chosen) are read with their field paths (stream/info.py);
every number, boolean or string field outside the header becomes a feature of the robot, named
from its topic and path (`/odom` `msg.twist.twist.linear.x` → `OdomTwistTwistLinearX`).  Three
files are written: a Turtle ontology (a sort `Robot`, the robot object, each feature a unary
relation over robots), the SSL_T specs binding each feature to its topic and field, and a
config naming them, which `match` and `monitor` take as they are.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .errors import DkError
from .inputs.files import write_atomic
from .stream.info import inspect

ROBOT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
SKIPPED = "msg.header."  # stamps and frame ids: the clock's, not the robot's


@dataclass(frozen=True, slots=True)
class StarterFeature:
    name: str  # the feature (an OWL class), as formulas write it: `Name[robot]`
    topic: str
    field: str
    ros_type: str
    kind: str  # number, bool or string


@dataclass(frozen=True, slots=True)
class Starter:
    """What `init` wrote: the config, ontology and specs, and the features they declare."""

    config: Path
    ontology: Path
    specs: Path
    robot: str
    features: tuple[StarterFeature, ...]


def feature_name(topic: str, field: str) -> str:
    """`/odom`, `msg.twist.twist.linear.x` → `OdomTwistTwistLinearX`."""
    words = [*topic.strip("/").split("/"), *re.split(r"[.]", field.removeprefix("msg."))]
    return "".join(part[:1].upper() + part[1:] for w in words for part in w.split("_") if part)


def init(
    sources: Sequence[str | Path],
    folder: Path,
    *,
    robot: str = "robot",
    topics: Sequence[str] = (),
    msg: Sequence[Path] = (),
    typestore: str | None = None,
) -> Starter:
    """A starter model of `robot` from the recordings' topics (`topics`: only these) in
    `folder` (made if it does not exist): ROBOT.ttl, ROBOT.sslt and ROBOT.toml, none of which
    may exist yet."""
    if not ROBOT.match(robot):
        raise DkError(f"--robot {robot!r}: letters, digits and _, not starting with a digit")
    if folder.exists() and not folder.is_dir():
        raise DkError(f"{folder}: not a directory")
    files = {s: folder / f"{robot}.{s}" for s in ("ttl", "sslt", "toml")}
    for path in files.values():
        if path.exists():
            raise DkError(f"{path}: exists already (init writes new files only)")
    infos = inspect(sources, fields=True, msg=msg, typestore=typestore)[0]
    found = {t.name: t for info in infos for t in info.topics}
    for topic in topics:
        if topic not in found:
            raise DkError(f"--topics {topic}: in no recording (topics: {', '.join(found)})")
    chosen = [found[t] for t in topics] if topics else list(found.values())
    features: dict[str, StarterFeature] = {}
    specs = []
    for t in chosen:
        own = []
        for f in t.fields:
            if f.path.startswith(SKIPPED) or "[" in f.path:
                continue
            name = feature_name(t.name, f.path)
            if name in features:  # two paths spelt alike: the later is left out
                continue
            features[name] = StarterFeature(name, t.name, f.path, f.ros_type, f.kind)
            own.append(f"{name}({robot}) = {f.path}")
        if own:
            specs.append(f"topic {t.name}:{t.msgtype} contains " + ",\n    ".join(own))
    if not features:
        raise DkError(
            "no number, boolean or string field outside the header in "
            + (", ".join(topics) if topics else "the recordings")
        )
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DkError(f"{folder}: cannot be made ({exc.strerror})") from None
    write_atomic(files["ttl"], _ontology(robot, features.values()).encode())
    header = f"# {robot}'s topics, from {', '.join(map(str, sources))} (dkreason init)\n"
    write_atomic(files["sslt"], (header + "\n".join(specs) + "\n").encode())
    config = (
        f"# {robot}: a starter model (dkreason init); rename features in both files at will\n"
        f'local = "{robot}"\n\n[platforms.{robot}]\n'
        f'ontology = "{files["ttl"].name}"\nspecs = "{files["sslt"].name}"\n'
    )
    write_atomic(files["toml"], config.encode())
    return Starter(files["toml"], files["ttl"], files["sslt"], robot, tuple(features.values()))


def _ontology(robot: str, features: Iterable[StarterFeature]) -> str:
    lines = [
        f"@prefix : <http://example.org/{robot}#> .",
        "@prefix owl: <http://www.w3.org/2002/07/owl#> .",
        "@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .",
        "",
        f"# {robot}: a starter ontology (dkreason init).  Each feature is a unary relation over",
        "# robots; add sorts, objects and features as the robot's world needs them.",
        ":Robot a owl:Class .",
        ":UnaryRelation a owl:Class .",
        ":arg1 a owl:ObjectProperty .",
        f":{robot} a owl:NamedIndividual, :Robot .",
        "",
    ]
    for f in features:
        lines += [
            f"# {f.topic} {f.field} ({f.ros_type})",
            f":{f.name} a owl:Class ; rdfs:subClassOf [ a owl:Class ; owl:intersectionOf (",
            "    :UnaryRelation [ a owl:Restriction ; owl:onProperty :arg1 ; "
            "owl:allValuesFrom :Robot ] ) ] .",
        ]
    return "\n".join(lines) + "\n"
