"""Why a topic was matched, and why another was not — computed on demand.

`replay` re-derives a fact from the loaded rule files' clauses (so a rule an extension adds is
cited like a shipped one), `provenance` says where each told fact comes from, `why` and
`whynot` read the policy's relations for one topic, `render` writes the answer as text, JSON
or dot.
"""

from .explanation import Explanation, FeatureExplanation, explain
from .render import to_dot, to_json, to_text
from .replay import Failure, Proof
from .why import TopicWhy
from .whynot import TopicWhyNot

__all__ = [
    "Explanation",
    "Failure",
    "FeatureExplanation",
    "Proof",
    "TopicWhy",
    "TopicWhyNot",
    "explain",
    "to_dot",
    "to_json",
    "to_text",
]
