"""dkreason: semantically grounded stream reasoning for robots.

    from dkreason import KnowledgeManager
    km = KnowledgeManager.from_config("examples/federation.toml")
    request = km.check_formula("forall x in UAV: always (Altitude[x] > 10)")
"""

from .errors import DkError, ParseError, SourceError, Span
from .manager import KnowledgeManager
from .model import (
    FeatureRequest,
    GroundFeature,
    StreamRequest,
    TopicArg,
    TopicFeature,
    TopicMatch,
    TopicSpec,
)

__all__ = [
    "DkError",
    "FeatureRequest",
    "GroundFeature",
    "KnowledgeManager",
    "ParseError",
    "SourceError",
    "Span",
    "StreamRequest",
    "TopicArg",
    "TopicFeature",
    "TopicMatch",
    "TopicSpec",
]
