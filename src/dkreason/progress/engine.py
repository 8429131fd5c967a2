"""The one contract between the progressor and its progression engines, checked by mypy: the
general node graph (general.py) and the generated fused monitors (fused.py).

The progressor splits a formula into its top-level conjuncts (parts) and gives each to an
engine; the formula's verdict is their Kleene conjunction.  An engine judges each part from
the next state on and reports its value once, by `finish` at the latest: False with a `Why`
phrased by witness.py (so both engines explain alike), True, or None (unknown for good, with
a `Why` holding the window the end of the data cut off, if one did).  It tells the progressor
which features its undecided parts read were unknown at each state, for the unknown
verdicts' witnesses.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Protocol, TypeVar

from ..model import FeatureKey
from ..parse.formula import Formula
from .witness import Time, Why

Report = Callable[[bool | None, Why | None], None]
"""A part's value and, when false, why: the reason at its first state (witness.refuted);
when unknown, a reason holding the cut window (witness.cut_of) if the end of the data cut one."""

Unknown = Callable[[Iterable[FeatureKey], int, Any], None]
"""These features were unknown at the state at this position (and time, as given)."""

Timer = Callable[[Time], None]
"""A window will have ended by this time: with no state before it, `advance` to it decides
something (told when a position starts waiting where none did; later ones end later)."""


class Engine(Protocol):
    """What the progressor asks of a progression engine."""

    def add(self, part: Formula, report: Report) -> bool:
        """Judge `part` (quantifier-free, in stream units) from the next state on; False when
        this engine does not take formulas of its shape."""
        ...

    def step(self, pos: int, t: Time, values: Mapping[FeatureKey, Any], given: Any) -> None:
        """One state: its position, exact time, every feature's value, the time as given."""
        ...

    def advance(self, t: Time) -> None:
        """No state until after t (the stream passed it): the parts whose windows ended by
        then report, as a state after t would make them (what it reads left aside)."""
        ...

    def deadline(self) -> Time | None:
        """The earliest end of a window a part waits on (None: none)."""
        ...

    def finish(self, cut: Time | None) -> None:
        """End of stream: every part that saw a state reports.  `cut`: the end of the data (at
        or after the last state); a bounded window reaching past it leaves its value unknown.
        None: every window closes at the last state (the finite-trace semantics).  Unbounded
        operators keep their finite-trace values either way."""
        ...


V = TypeVar("V", covariant=True)


class Stepper(Protocol[V]):
    """A progressor's step for one checked state: its verdicts."""

    def __call__(
        self, t: Time, values: Mapping[FeatureKey, Any], given: Any = None
    ) -> Sequence[V]: ...


Entry = Callable[[Any, Any], list[Any]]
"""A progressor's step for a state as its caller gives it (`Progressor.step`: time and values
as given, checked): its verdicts."""


Append = Callable[[Any], None]
"""A list's append: what keeps a state's time or a feature's value (progress.kept)."""

Held = Callable[[], tuple[int, Any]]
"""The position and time (as given) of the last state a fused fast step took."""
