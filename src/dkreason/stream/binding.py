"""Which recording topics carry a spec topic, and several recordings read as one.

A spec topic's name is a ROS graph name.  On a platform with a `namespace` (config) a relative
name resolves under it as ROS resolves it (`imu/data` on `/robot1` is `/robot1/imu/data`); an
absolute name stands for itself.  A platform without a namespace keeps the thesis' layout: a
relative name `T` of platform P is `/P/T`, and also the bare `/T` on the local platform, or on
any platform when no other platform's spec uses the name T (a federation recorded under its
topics' own names: `carstopic1`, `uastopic5`).  A recording name without its leading slash is
the same name.  A recording given as `PLATFORM=PATH` binds only to that platform's specs, by the
names that robot records (its topics are presented as `PLATFORM:/name`).
"""

from __future__ import annotations

import heapq
from collections.abc import Collection, Generator, Iterator, Mapping, Sequence
from dataclasses import dataclass
from operator import attrgetter
from pathlib import Path

from ..errors import DkError
from ..model import TopicMatch, ros_name
from .sources import Message, Raw, Source, Wanted, open_source

CLOCKS = ("auto", "header", "record")


def recording_names(
    m: TopicMatch, local: str, namespace: str | None, shared: Collection[str] = ()
) -> list[str]:
    """The recording topic names that may carry `m`, best first: first as a recording given
    for m's platform (`PLATFORM=PATH`) names it, then as any recording does.  `shared`: the
    spec topic names several platforms use (`StreamRequest.shared_names`)."""
    t = m.topic
    own = ros_name(t, namespace)
    if t.startswith("/") or namespace is not None:
        anywhere = [own]
    else:  # the thesis' layout: /P/T; the bare /T on the local platform, or if unshared
        bare = m.platform == local or t not in shared
        anywhere = [f"/{m.platform}/{t}", *([own] if bare else [])]
    return [
        f"{m.platform}:{own}",
        f"{m.platform}:{own[1:]}",
        *(n for full in anywhere for n in (full, full[1:])),
    ]


def message_type_fits(recorded: str, written: str) -> bool:
    """`turtlesim/msg/Pose` (ROS 2) or `turtlesim/Pose` (ROS 1) is what a spec writes as
    `Pose`, `turtlesim/Pose` or `turtlesim/msg/Pose`."""

    def parts(t: str) -> tuple[str | None, str]:
        pieces = t.split("/")
        return (pieces[0] if len(pieces) > 1 else None), pieces[-1]

    (rec_pkg, rec_name), (pkg, name) = parts(recorded), parts(written)
    return rec_name == name and (pkg is None or pkg == rec_pkg)


@dataclass(frozen=True, slots=True)
class Recording:
    source: Source
    platform: str | None  # PLATFORM=PATH: its topics bind to that platform's specs only


class Recordings:
    """Several recordings as one source, merged by record time as they stream (each is read
    in order, so memory stays flat); `remap` reads a recording topic under another name."""

    def __init__(
        self,
        recordings: Sequence[Recording],
        remap: Mapping[str, str] | None = None,
        clock: str = "auto",
    ) -> None:
        if not recordings:
            raise DkError("no recording given")
        self.parts = list(recordings)
        self.remap = {_slash(a): b for a, b in (remap or {}).items()}
        self.unmap = {_slash(b): a for a, b in self.remap.items()}
        self.name = ", ".join(r.source.name for r in self.parts)
        notes = [n for r in self.parts if (n := getattr(r.source, "note", None))]
        self.clock = self._clock() if clock == "auto" else clock
        if clock == "auto" and self.clock == "record":
            notes.append(
                "the header stamps run on another clock than the record time "
                f"(about {self._offset:.0f} s apart: simulated time?); valid times "
                "are the record time (--clock header to use the stamps)"
            )
        self.note = "; ".join(notes)

    _offset = 0.0
    stamped = False  # whether the first messages looked at carry header stamps
    SAMPLE = 200  # messages looked at to choose the clock
    APART = 60 * 10**9  # stamps further than this from the record time: another clock

    def _clock(self) -> str:
        """'header' unless the first stamped messages are on another clock than the record
        time (a simulator's, or a robot whose clock was never set), then 'record'."""
        offsets: list[int] = []
        for r in self.parts:
            topics = r.source.types()  # none known (JSON lines): times are written, not stamped
            messages = r.source.messages({t: [] for t in topics}) if topics else iter(())
            try:
                for _, (_, available, valid, _) in zip(range(self.SAMPLE), messages, strict=False):
                    if valid != available:
                        offsets.append(available - valid)
            except DkError:  # damage this early is reported when the recording is read
                pass
        if not offsets:
            return "header"
        self.stamped = True
        median = sorted(offsets)[len(offsets) // 2]
        self._offset = median / 10**9
        return "record" if abs(median) > self.APART else "header"

    def _shown(self, r: Recording, own: str) -> str:
        name = self.remap.get(_slash(own), own)
        return f"{r.platform}:{name}" if r.platform else name

    def _own(self, r: Recording, shown: str) -> str | None:
        """The recording's own name for a presented one (None: not one of its topics)."""
        if r.platform is not None:
            if not shown.startswith(f"{r.platform}:"):
                return None
            shown = shown[len(r.platform) + 1 :]
        return self.unmap.get(_slash(shown), shown)

    def types(self) -> dict[str, str]:
        """Known only when every recording knows its topics (JSON lines do not)."""
        out: dict[str, str] = {}
        for r in self.parts:
            types = r.source.types()
            if not types:
                return {}
            out |= {self._shown(r, own): t for own, t in types.items()}
        return out

    def _holder(self, topic: str) -> tuple[Source, str] | None:
        """The recording holding a presented topic, and its own name for it."""
        for r in self.parts:
            own = self._own(r, topic)
            if own is not None and own in r.source.types():
                return r.source, own
        return None

    def check_field(self, topic: str, field: str) -> str | None:
        held = self._holder(topic)
        return None if held is None else held[0].check_field(held[1], field)

    def field_kind(self, topic: str, field: str) -> tuple[str, str] | None:
        held = self._holder(topic)
        return None if held is None else held[0].field_kind(held[1], field)

    def first_record(self) -> int | None:
        """The earliest of the recordings' starts known (each is known once it is read)."""
        starts = [s for r in self.parts if (s := r.source.first_record()) is not None]
        return min(starts, default=None)

    def last_record(self) -> int | None:
        ends = [r.source.last_record() for r in self.parts]
        return None if None in ends else max(e for e in ends if e is not None)

    def count(self, topics: set[str] | None) -> int | None:
        counts = [
            r.source.count(
                None
                if topics is None
                else {o for t in topics if (o := self._own(r, t)) is not None}
            )
            for r in self.parts
        ]
        return None if None in counts else sum(c for c in counts if c is not None)

    def messages(self, wanted: Wanted) -> Iterator[Message]:
        return _merged([self._stream(r, wanted) for r in self.parts])

    def _stream(self, r: Recording, wanted: Wanted) -> Iterator[Message]:
        shown: dict[str, str] = {}
        own: Wanted = {}
        for topic, fields in wanted.items():
            name = self._own(r, topic)
            if name is not None and name not in own:
                own[name], shown[name] = fields, topic
        messages = r.source.messages(own)
        if self.clock != "record" and all(a == b for a, b in shown.items()):
            return messages  # nothing to rename or retime: no layer per message
        return self._renamed(messages, shown)

    def _renamed(self, messages: Iterator[Message], shown: dict[str, str]) -> Iterator[Message]:
        record = self.clock == "record"
        for topic, available, valid, values in messages:
            yield shown[topic], available, available if record else valid, values

    def raw(self, topics: Collection[str]) -> Generator[Raw]:
        """The messages on `topics` (as presented) as recorded, under each recording's own
        names (so a copy replays with the same `--remap`), merged by record time."""
        streams = []
        for r in self.parts:
            own = {o for t in topics if (o := self._own(r, t)) is not None}
            read = getattr(r.source, "raw", None)
            if read is None:
                raise DkError(
                    f"{r.source.name}: its messages cannot be copied (JSON lines, or damaged)"
                )
            streams.append(read(own))
        return heapq.merge(*streams, key=attrgetter("time"))

    def close(self) -> None:
        for r in self.parts:
            r.source.close()


def open_recordings(
    given: Sequence[str | Path],
    platforms: Collection[str] = (),
    *,
    remap: Mapping[str, str] | Sequence[str] | None = None,
    clock: str = "auto",
    msg: Sequence[Path] = (),
    typestore: str | None = None,
) -> Recordings:
    """The recordings of one run as one source, as `dkreason monitor --source` takes them:
    each `[PLATFORM=]PATH` (a path that exists is a path, even with an `=` in it), `remap` as
    `{FROM: TO}` or `FROM:=TO` rules, the clock (auto, header, record), `--msg` definitions and
    a standard typestore.  On an error every recording opened so far is closed."""
    if clock not in CLOCKS:
        raise DkError(f"clock {clock!r}: expected one of {', '.join(CLOCKS)}")
    rules = remap if isinstance(remap, Mapping) else remaps(remap or ())
    parts: list[Recording] = []
    try:
        for item in given:
            platform, sep, path = str(item).partition("=")
            if sep and platform not in platforms and not Path(item).exists():
                raise DkError(
                    f"--source {item}: {platform!r} is not a platform of the config "
                    f"(platforms: {', '.join(sorted(platforms)) or 'none'})"
                )
            if not sep or platform not in platforms:
                platform, path = "", str(item)
            parts.append(Recording(open_source(Path(path), msg, typestore), platform or None))
        return Recordings(parts, rules, clock)
    except BaseException:
        for r in parts:
            r.source.close()
        raise


RECORDINGS = (".bag", ".mcap", ".db3", ".jsonl")  # what a folder is searched for, and bag folders


def is_bag_folder(path: Path) -> bool:
    """A ROS 2 bag folder: one recording, however many storage files it holds."""
    return (path / "metadata.yaml").is_file()


def recordings_in(folder: Path) -> Iterator[Path]:
    """The recordings in a folder that is not itself a bag folder, searched through."""
    for entry in sorted(folder.iterdir()):
        if entry.is_dir():
            yield from [entry] if is_bag_folder(entry) else recordings_in(entry)
        elif entry.suffix in RECORDINGS:
            yield entry


def expand_folders(given: Sequence[str | Path]) -> list[str]:
    """Each `[PLATFORM=]PATH`, a folder holding several recordings (not a bag folder) as
    those recordings (`dkreason info`); a folder holding none is an error."""
    out: list[str] = []
    for item in given:
        platform, sep, rest = str(item).partition("=")
        path = Path(rest if sep and not Path(item).exists() else item)
        prefix = f"{platform}=" if sep and not Path(item).exists() else ""
        if not path.is_dir() or is_bag_folder(path):
            out.append(str(item))
            continue
        found = [f"{prefix}{p}" for p in recordings_in(path)]
        if not found:
            raise DkError(
                f"{path}: no recording in this folder (.bag, .mcap, .db3, .jsonl files "
                "or ROS 2 bag folders with a metadata.yaml)"
            )
        out += found
    return out


def remaps(rules: Sequence[str]) -> dict[str, str]:
    """`FROM:=TO` rules (ROS's remapping syntax) as a mapping; a topic remapped twice is an
    error, not the last rule silently."""
    out: dict[str, str] = {}
    for rule in rules:
        old, sep, new = rule.partition(":=")
        if not sep or not old or not new:
            raise DkError(f"--remap {rule!r}: expected FROM:=TO")
        if out.get(old, new) != new:
            raise DkError(f"--remap {rule!r}: {old} is already remapped to {out[old]}")
        out[old] = new
    return out


def _merged(streams: Sequence[Iterator[Message]]) -> Iterator[Message]:
    """Messages of several recordings by record time; on equal times the earlier recording's
    first (as `heapq.merge`).  Merged in pairs: a message costs one comparison a level, not a
    heap step and a key call."""
    if len(streams) == 1:
        return streams[0]
    half = len(streams) // 2
    return _two(_merged(streams[:half]), _merged(streams[half:]))


def _two(a: Iterator[Message], b: Iterator[Message]) -> Iterator[Message]:
    y = next(b, None)
    if y is None:
        yield from a
        return
    for x in a:
        while y[1] < x[1]:  # b's earlier messages first
            yield y
            y = next(b, None)
            if y is None:
                yield x
                yield from a
                return
        yield x
    yield y
    yield from b


def _slash(name: str) -> str:
    return name if name.startswith("/") else "/" + name
