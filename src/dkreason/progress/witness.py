"""Witnesses, phrased in one place for both engines.

A decision's reason is a chain of `Why` links ("X is false at 3, because …").  Each kind of
link is made here (a state formula's value, a window that closed or that the end of the data
cut off, a value its subformula settled, a trigger whose response failed), and so is the
verdict's witness text, so the same formula and trace read the same whichever engine judged
them (tests/test_progress.py checks it on random formulas and traces).  Subformulas are quoted
as `parse.formula.unparse` prints them: re-parsed, each gives the same tree.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..inputs.numbers import decimal
from ..model import FeatureKey
from .verdict import UnknownSpan, value_text

Time = int | Fraction
SHOWN = 10  # spans a witness names; the rest are counted
UNDECIDED = "the data left it undecided: "  # how an unknown verdict's witness begins


@dataclass(frozen=True, slots=True)
class Clock:
    """How a witness says a time: in seconds (`unit`: seconds per time unit of the stream) and,
    with an `origin` (a stream time, asked when a witness is phrased: the run's start, which
    only the monitor knows), as `t+…` seconds from it."""

    unit: Fraction | int = 1
    origin: Callable[[], Time | None] | None = None

    def time(self, t: Any) -> str:
        """A time: `t+0.02` from the origin (`t-0.02` before it), else as the stream has it
        (`oo`: none)."""
        if t is None:
            return "oo"
        origin = None if self.origin is None else self.origin()
        if not isinstance(t, int | Fraction):
            return str(t)  # as the caller gave it
        if origin is None:
            return decimal(t * self.unit)
        since = Fraction(t - origin) * self.unit  # negative for a stamp before the start
        return f"t{'-' if since < 0 else '+'}{decimal(abs(since))}"

    def at(self, t: Any) -> str:
        """A time after "at": `t+0.02 s` from the origin."""
        return self.time(t) + (" s" if self.origin is not None else "")

    def span(self, a: Any, b: Any) -> str:
        return f"[{self.time(a)}, {self.time(b)}]"

    def seconds(self, d: Time) -> str:
        """A duration: `3.9 s`."""
        return f"{decimal(d * self.unit)} s"


class Why:
    """Why a value was decided at a position: built only on decisions.  `plain` links only
    restate a value ("X is false at 3"); their cause says why.  A `cut` link is a time window
    the end of the data cut off (what left the value open)."""

    __slots__ = ("text", "at", "detail", "cause", "plain", "cut")

    def __init__(
        self,
        text: str,
        at: Time,
        detail: str,
        cause: Why | None = None,
        plain: bool = False,
        cut: bool = False,
    ) -> None:
        self.text, self.at, self.detail, self.cause = text, at, detail, cause
        self.plain, self.cut = plain, cut

    def render(self) -> str:
        own = f"{self.text} {self.detail}"
        return own if self.cause is None else f"{own}, because {self.cause.render()}"

    def __repr__(self) -> str:
        return f"Why({self.render()!r})"


def word(value: Any) -> str:
    return {True: "true", False: "false", None: "unknown"}.get(value, "pending")


def state_was(
    text: str,
    t: Time,
    value: bool | None,
    keys: Iterable[FeatureKey],
    values: Any,
    clock: Clock,
) -> Why:
    """A state formula's value at t, with the values it read: `X > 1 was false at 3 (X = 0)`."""
    shown = ", ".join(f"{k} = {value_text(values[k])}" for k in keys)
    said = {True: "held", False: "was false", None: "was unknown"}[value]
    return Why(text, t, f"{said} at {clock.at(t)}" + (f" ({shown})" if shown else ""))


def settled(text: str, t: Time, value: Any, cause: Why | None, clock: Clock) -> Why:
    """A subformula's value at t, for the reason `cause` gives (a plain link)."""
    return Why(text, t, f"is {word(value)} at {clock.at(t)}", cause, plain=True)


def window_closed(
    text: str,
    child: str,
    ti: Time,
    lo: Time,
    hi: Time | None,
    value: bool | None,
    clock: Clock,
) -> Why:
    """The window [ti + lo, ti + hi] of `text` closed: its `child` never held within it
    (eventually, false), held throughout (always, true), or was unknown somewhere in it."""
    within = clock.span(ti + lo, None if hi is None else ti + hi)
    how = (
        "was unknown within"
        if value is None
        else "held throughout"
        if value
        else "never held within"
    )
    return settled(text, ti, value, Why(child, ti, f"{how} {within}"), clock)


def window_cut(text: str, ti: Time, lo: Time, hi: Time, end: Time, clock: Clock) -> Why:
    """The window [ti + lo, ti + hi] of `text` reaches past `end`, the end of the data: what
    it decides is not in the data (a `cut` link)."""
    seen = max(end - ti - lo, 0)
    return Why(
        f"{text}: window {clock.span(ti + lo, ti + hi)}",
        ti,
        f"cut off at the end of the data, {clock.seconds(seen)} of {clock.seconds(hi - lo)} seen",
        cut=True,
    )


def cut_of(why: Why | None) -> Why | None:
    """The window cut off at the end of the data that left a value open, if one did."""
    while why is not None and not why.cut:
        why = why.cause
    return why


def but(trigger: str, ti: Time, why: Why, clock: Clock) -> Why:
    """`A -> B` (or `not A or B`) is false at ti: A held, but `why` B did not (its plain link
    left out: the sentence says when)."""
    if why.plain and why.cause is not None:
        why = why.cause
    return Why(f"{trigger} held at {clock.at(ti)}, but {why.text}", why.at, why.detail, why.cause)


def next_late(text: str, ti: Time, gap: Time | None, clock: Clock) -> Why:
    """`next[a, b]` is false at ti: the next state came outside [a, b] (`gap` later), or never."""
    late = f"the next state came {clock.time(gap)} later" if gap is not None else "no next state"
    return Why(text, ti, f"is false at {clock.at(ti)}: {late}")


def since(why: Why) -> Time:
    """The earliest time the witness of `why` names: where its window begins (an invariant
    violated at t: at t, not at the formula's first state, which only restates it)."""
    why = _told(why)
    first, link = why.at, why.cause
    while link is not None:
        first, link = min(first, link.at), link.cause
    return first


def refuted(why: Why, decided: Any, clock: Clock) -> str:
    """A false verdict's witness, led by the decision: when it was decided, then the reason
    for the value at the formula's first state (a link only restating it left out)."""
    return f"violated at {clock.at(decided)}: {_told(why).render()}"


def _told(why: Why) -> Why:
    """The reason a witness tells: a first link only restating the formula is left out."""
    return why.cause if why.plain and why.cause is not None else why


def undecided(
    spans: Iterable[UnknownSpan], started: bool, clock: Clock, pending: str | None = None
) -> str:
    """An unknown verdict's witness: where the features it reads were unknown (the first
    `SHOWN`, and how many more), and the window the end of the data cut off."""
    said = [_unknown(s, clock) for s in spans]
    if len(said) > SHOWN:
        said[SHOWN:] = [f"and {len(said) - SHOWN} more"]
    if pending is not None:
        said.append(pending)
    if said:
        return UNDECIDED + "; ".join(said)
    return UNDECIDED + (
        "a value it computes is undefined where it would be decided (the square root of a "
        "negative, a division by 0)"
        if started
        else "no state was seen"
    )


def _unknown(span: UnknownSpan, clock: Clock) -> str:
    if not span.silent:
        if span.start == span.end:
            return f"{span.feature} unknown at {clock.at(span.start)}"
        return f"{span.feature} unknown from {clock.at(span.start)} to {clock.at(span.end)}"
    if span.start is None:
        return f"{span.feature} never observed"
    before = clock.seconds(span.end - span.start)
    return f"{span.feature} silent from {clock.at(span.start)} ({before} before the end)"
