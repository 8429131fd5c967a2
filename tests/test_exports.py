"""The public API is what `dkreason.__all__` says, and nothing else by accident."""

import dkreason


def test_public_names_are_pinned() -> None:
    assert dkreason.__all__ == [
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
    assert all(hasattr(dkreason, name) for name in dkreason.__all__)
