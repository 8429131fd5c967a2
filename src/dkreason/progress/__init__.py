"""Formula Progressor (thesis 2.3.2, 4.4): incremental MTL verdicts over a state stream."""

from .progressor import Progressor
from .verdict import InstanceVerdict, UnknownSpan, Verdict

__all__ = ["InstanceVerdict", "Progressor", "UnknownSpan", "Verdict"]
