"""Declared stream quality against what arrives (thesis 8.2): each recording topic whose spec
declares a rate or a delay is watched while it is replayed, and what breaks the declaration is
a stream-constraint violation like those of thesis listing 5.2.

- `declared_rate`: fewer than RATE_SHARE of the samples the declared rate gives in the last
  RATE_WINDOW declared periods (judged once the topic has run that long), or no sample at
  all for that long (judged as time passes, from the other topics' messages);
- `declared_delay`: a sample's record time lags its header stamp by more than the declared
  delay (topics without stamps have none).

Each kind is said at most once per REPORT_EVERY of record time and topic, so a degraded source
is a line now and then, not one per message.  A topic with a declared rate that sends nothing
for more than `set_aside_after` declared periods is set aside (a `Move` told to the monitor,
which matches its features again without it) and taken back at its next sample; one that
never sends is silent from the start of the stream (or from when it was matched, if later),
so a topic absent from a recording, or never published live, is set aside alike.  `observe`
measures what a recording's topic runs at, for `dkreason info --timing`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from ..inputs.numbers import decimal
from ..model import FeatureKey, stream_name
from .units import NS, seconds_text

RATE_WINDOW = 10  # declared periods a topic's rate is judged over
RATE_SHARE = Fraction(9, 10)  # of the declared rate, the least a topic may run at
REPORT_EVERY = NS  # a topic's violations of one kind: at most one a second (record time)

Found = tuple[str, FeatureKey, str, int, str]  # kind, feature, stream, time (ns), detail


@dataclass(frozen=True, slots=True)
class Move:
    """A source set aside (`aside`: its samples stopped) or taken back (a sample came), at
    `time` (ns, record time), with the reason in words."""

    platform: str
    topic: str  # as its spec names it
    aside: bool
    time: int
    reason: str


@dataclass(slots=True)
class _Watched:
    feature: FeatureKey  # the first feature the topic feeds (a violation names one)
    platform: str
    topic: str  # as its spec names it
    stream: str  # platform/topic, as violations name it
    rate: Fraction | None
    delay: int | None  # ns
    window: int  # ns: RATE_WINDOW declared periods
    arrivals: deque[int] = field(default_factory=deque)
    first: int | None = None
    quiet: dict[str, int] = field(default_factory=dict)  # kind → said again from then on
    aside: bool = False
    since: int | None = None  # ns: its silence counts from here before its first sample


class QualityWatch:
    """The recording topics whose specs declare their quality, what they broke, and which
    are set aside (`moved` is told each change)."""

    def __init__(
        self, set_aside_after: int = 0, moved: Callable[[Move], None] | None = None
    ) -> None:
        """`set_aside_after`: declared periods without a sample before a topic is set aside
        (0: never)."""
        # recording topic → the spec topic watched (the names it may be read by share one)
        self.topics: dict[str, _Watched] = {}
        self.watched: dict[tuple[str, str], _Watched] = {}  # (platform, spec topic) → it
        self.start: int | None = None  # ns: the start of the stream, once known (`begin`)
        self.set_aside_after, self.moved = set_aside_after, moved
        # the record time (ns) after which `silent` may have something to say: a replay asks
        # it at the first message past it, of any topic, whether or not a state is due then
        self.due: float = math.inf

    def declare(
        self,
        names: Iterable[str],
        feature: FeatureKey,
        platform: str,
        spec_topic: str,
        rate: Fraction | None,
        delay: Fraction | None,
        since: int | None = None,
    ) -> None:
        """Watch `platform/spec_topic`, read as any of the recording topics `names` (none: in
        no recording), once however many features it feeds (it stays watched when it is set
        aside, so its return is seen).  Silent until its first sample from `since` (ns;
        None: from the start of the stream, `begin`)."""
        if rate is None and delay is None:
            return
        w = self.watched.get((platform, spec_topic))
        if w is None:
            window = round(RATE_WINDOW * NS / rate) if rate else 0
            ns = None if delay is None else round(delay * NS)
            stream = stream_name(platform, spec_topic)
            w = _Watched(feature, platform, spec_topic, stream, rate, ns, window)
            w.since = self.start if since is None else since
            self.watched[(platform, spec_topic)] = w
            if rate and w.since is not None:
                self.due = min(self.due, self._due(w))
        for name in names:
            self.topics.setdefault(name, w)

    def begin(self, at: int) -> None:
        """The stream starts at `at` (ns; once): the topics that have sent nothing are silent
        from there."""
        if self.start is not None:
            return
        self.start = at
        for w in self.watched.values():
            if w.since is None:
                w.since = at
            if w.rate:
                self.due = min(self.due, self._due(w))

    def aside(self) -> list[str]:
        """The recording topics set aside now."""
        return [name for name, w in self.topics.items() if w.aside]

    def sample(self, topic: str, available: int, valid: int) -> list[Found]:
        """A message of a watched topic: its delay, and the rate over the window it ends (a
        topic set aside is taken back)."""
        w = self.topics[topic]
        out = []
        if w.aside:
            w.aside = False
            last = w.arrivals[-1] if w.arrivals else w.since
            assert last is not None  # set aside: it had been silent since then
            gap = seconds_text(available - last)
            self._move(w, False, available, f"a sample came after {gap} s without one")
        if w.delay is not None and available - valid > w.delay:
            lag = seconds_text(available - valid)
            declared = seconds_text(w.delay)
            out += self._say(w, "declared_delay", available, f"delay {lag} s exceeds {declared} s")
        if w.rate is None:
            return out
        arrivals = w.arrivals
        arrivals.append(available)
        self.due = min(self.due, self._due(w))
        if w.first is None:
            w.first = available
        while arrivals[0] <= available - w.window:
            arrivals.popleft()
        if w.first <= available - w.window and len(arrivals) < RATE_WINDOW * RATE_SHARE:
            seen = Fraction(len(arrivals) * NS, w.window)
            out += self._say(
                w,
                "declared_rate",
                available,
                f"{len(arrivals)} samples in the last {seconds_text(w.window)} s "
                f"({decimal(round(seen, 3))} Hz), below the declared {decimal(w.rate)} Hz",
            )
        return out

    def silent(self, now: int) -> list[Found]:
        """Topics with a declared rate that have sent nothing for a window by `now`; those
        silent for more than `set_aside_after` declared periods are set aside."""
        out = []
        after = self.set_aside_after
        self.due = math.inf
        for w in self.watched.values():
            last = w.arrivals[-1] if w.arrivals else w.since
            if w.rate is None or last is None:
                continue
            quiet = now - last
            if after and not w.aside and quiet * w.rate > after * NS:
                w.aside = True
                over = f"over {after} periods of the declared {decimal(w.rate)} Hz"
                self._move(
                    w,
                    True,
                    now,
                    f"no sample for {seconds_text(quiet)} s, {over}"
                    if w.arrivals
                    else f"no sample since {'the start' if last == self.start else 'matched'} "
                    f"({seconds_text(quiet)} s, {over})",
                )
            if w.arrivals and quiet > w.window:
                out += self._say(
                    w,
                    "declared_rate",
                    now,
                    f"no sample for {seconds_text(quiet)} s, below the declared "
                    f"{decimal(w.rate)} Hz",
                )
            self.due = min(self.due, self._due(w))
        return out

    def _due(self, w: _Watched) -> float:
        """When `silent` next has something to say of `w` (a topic with a declared rate and
        a sample, or a start to be silent from): past its window without a sample (once it
        may be said again; not before its first), or past `set_aside_after` periods (unless
        it is aside)."""
        assert w.rate is not None
        last = w.arrivals[-1] if w.arrivals else w.since
        assert last is not None
        due: float = math.inf
        if w.arrivals:
            due = max(last + w.window, w.quiet.get("declared_rate", 0) - 1)
        if self.set_aside_after and not w.aside:
            due = min(due, math.floor(last + self.set_aside_after * NS / w.rate))
        return due

    def _move(self, w: _Watched, aside: bool, at: int, reason: str) -> None:
        if self.moved is not None:
            self.moved(Move(w.platform, w.topic, aside, at, reason))

    def _say(self, w: _Watched, kind: str, at: int, detail: str) -> list[Found]:
        if at < w.quiet.get(kind, at):
            return []
        w.quiet[kind] = at + REPORT_EVERY
        return [(kind, w.feature, w.stream, at, detail)]


@dataclass(frozen=True, slots=True)
class Timing:
    """A topic as observed: its rate (Hz, one over each inter-arrival time: the median and
    the 5th percentile, its slow moments) and its delay (s, header stamp to record time: the
    median and the 95th percentile; None without stamps on the record clock)."""

    rate_median: float | None
    rate_p5: float | None
    delay_median: float | None
    delay_p95: float | None

    def to_json(self) -> dict[str, Any]:
        return {
            "rate": {"median": self.rate_median, "p5": self.rate_p5},
            "delay": {"median": self.delay_median, "p95": self.delay_p95},
        }


def observe(arrivals: Sequence[int], lags: Sequence[int] | None) -> Timing:
    """Timing from a topic's record times (ns, in order) and, if stamped, each message's lag
    of its record time behind its header stamp (ns)."""
    rates = sorted(NS / (b - a) for a, b in zip(arrivals, arrivals[1:], strict=False) if b > a)
    delays = sorted(lag / NS for lag in lags) if lags else []
    return Timing(
        _quantile(rates, 0.5),
        _quantile(rates, 0.05),
        _quantile(delays, 0.5),
        _quantile(delays, 0.95),
    )


def _quantile(xs: list[float], q: float) -> float | None:
    """The q-quantile of sorted `xs`, interpolated between the nearest ranks."""
    if not xs:
        return None
    at = q * (len(xs) - 1)
    lo = math.floor(at)
    hi = min(lo + 1, len(xs) - 1)
    return round(xs[lo] + (xs[hi] - xs[lo]) * (at - lo), 9)
