"""Formula Progressor (thesis 2.3.2, 4.4): incremental MTL verdicts over a state stream."""

from .progressor import Progressor, UnknownSpan, Verdict

__all__ = ["Progressor", "UnknownSpan", "Verdict"]
