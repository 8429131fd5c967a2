"""dkreason: semantically grounded stream reasoning for robots.

    from dkreason import KnowledgeManager, StreamPolicy
    km = KnowledgeManager.from_config("examples/federation.toml")
    request = km.check_formula("forall x in UAV: always (Altitude[x] > 10)")
    for event in km.monitor("forall c in Car: always (Speed[c] < 90)", "traffic.mcap",
                            StreamPolicy(max_age="2s")):  # the CLI's defaults otherwise
        print(event)            # a Verdict, Violation or Rerouted, as it happens; times in s

Every name but the errors loads on first use, so importing dkreason (and so starting the
CLI, whose module lives in this package) stays cheap.
"""

from typing import TYPE_CHECKING, Any

from .errors import DkError, ParseError, SourceError, Span

if TYPE_CHECKING:
    from .manager import KnowledgeManager
    from .model import (
        FeatureInfo,
        FeatureKey,
        FeatureRequest,
        GroundFeature,
        StreamRequest,
        TopicArg,
        TopicFeature,
        TopicMatch,
        TopicSpec,
    )
    from .monitor import Monitor, MonitorRun, Rerouted
    from .plan import FormulaPlan, Plan
    from .progress import Verdict
    from .stream.policy import StreamPolicy
    from .stream.processor import Violation
    from .stream.sources import PushSource

_LAZY = {
    "KnowledgeManager": "manager",
    **dict.fromkeys(
        (
            "FeatureInfo",
            "FeatureKey",
            "FeatureRequest",
            "GroundFeature",
            "StreamRequest",
            "TopicArg",
            "TopicFeature",
            "TopicMatch",
            "TopicSpec",
        ),
        "model",
    ),
    "Monitor": "monitor",
    "Plan": "plan",
    "FormulaPlan": "plan",
    "Verdict": "progress",
    "StreamPolicy": "stream.policy",
    "PushSource": "stream.sources",
    "MonitorRun": "monitor",
    "Rerouted": "monitor",
    "Violation": "stream.processor",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'dkreason' has no attribute {name!r}")


__all__ = [
    "DkError",
    "FeatureInfo",
    "FeatureKey",
    "FeatureRequest",
    "FormulaPlan",
    "GroundFeature",
    "KnowledgeManager",
    "Monitor",
    "MonitorRun",
    "ParseError",
    "Plan",
    "PushSource",
    "Rerouted",
    "SourceError",
    "Span",
    "StreamPolicy",
    "StreamRequest",
    "TopicArg",
    "TopicFeature",
    "TopicMatch",
    "TopicSpec",
    "Verdict",
    "Violation",
]
