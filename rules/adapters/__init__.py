"""Adapters: rule files deriving features from an ontology's triples (adapters = [...])."""
