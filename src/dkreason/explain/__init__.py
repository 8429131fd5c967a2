"""Why a topic was matched, and why another was not — computed on demand.

`replay` re-derives a fact from the loaded rule files' clauses (so a rule an extension adds is
cited like a shipped one), `provenance` says where each told fact comes from, `why` and
`whynot` read the policy's relations for one topic, `explanation` puts them together for a
formula, `render` writes the answer as text, JSON or dot.

What they ask of a policy (relevant_topic, match_result, and the steps why-not walks:
context, candidate, sound_candidate, matched_topic) is declared `query` in rules/schema.dl,
so a policy that lacks one is refused at load; the shipped relations they put in words of
their own (provenance.WORDED) are read only where the policy declares them as they read them.
So any policy that loads is explained: a proof that cannot be replayed is shown as the
policy's answer itself.
"""

from .explanation import Explanation, FeatureExplanation, exclusions, explain
from .render import render, to_dot, to_json, to_text
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
    "exclusions",
    "explain",
    "render",
    "to_dot",
    "to_json",
    "to_text",
]
