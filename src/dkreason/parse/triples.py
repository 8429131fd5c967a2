"""The triple store an ontology is read into: rdflib's graph API over flat indexes.

rdflib's default store keeps three nested dictionaries and a context map per triple, about
1.3 KB a triple: 100,000 class assertions took 134 MB, past the memory an input may cost
(issue 27: 50× the file or 100 MB).  An ontology is one graph without contexts, asked by
subject, object or predicate, so one set of triples and three flat indexes (a key to its one
triple, or to a list once it has more) answer every pattern at about 0.5 KB a triple.
"""

from __future__ import annotations

from collections.abc import Generator, Iterator
from typing import Any

from rdflib.graph import Graph
from rdflib.store import Store

Triple = tuple[Any, Any, Any]
_NO_CONTEXTS: tuple[Any, ...] = ()


class TripleStore(Store):
    """A store for one graph: no contexts, no formulas, no transactions."""

    context_aware = False
    formula_aware = False
    graph_aware = False
    transaction_aware = False

    def __init__(self) -> None:
        super().__init__()
        self.triples_held: set[Triple] = set()
        # subject, predicate, object → the one triple with it, or the list of them
        self.index: tuple[dict[Any, Any], dict[Any, Any], dict[Any, Any]] = ({}, {}, {})
        self.prefixes: dict[str, Any] = {}
        self.names: dict[Any, str] = {}

    def add(self, triple: Triple, context: Any, quoted: bool = False) -> None:
        if triple in self.triples_held:
            return
        self.triples_held.add(triple)
        for key, index in zip(triple, self.index, strict=True):
            held = index.get(key)
            if held is None:
                index[key] = triple
            elif type(held) is list:
                held.append(triple)
            else:
                index[key] = [held, triple]

    def remove(self, triple_pattern: Triple, context: Any = None) -> None:
        for triple, _ in list(self.triples(triple_pattern)):
            self.triples_held.discard(triple)
            for key, index in zip(triple, self.index, strict=True):
                held = index[key]
                if type(held) is list and len(held) > 1:
                    held.remove(triple)
                else:
                    del index[key]

    def triples(
        self, triple_pattern: Triple, context: Any = None
    ) -> Iterator[tuple[Triple, Iterator[Any]]]:
        s, p, o = triple_pattern
        if s is not None and p is not None and o is not None:
            if triple_pattern in self.triples_held:
                yield triple_pattern, iter(_NO_CONTEXTS)
            return
        # the most selective key given: a subject, else an object, else a predicate
        position, key = next(
            ((i, k) for i, k in ((0, s), (2, o), (1, p)) if k is not None), (None, None)
        )
        if position is None:
            candidates: Any = list(self.triples_held)
        else:
            held = self.index[position].get(key)
            candidates = () if held is None else held if type(held) is list else (held,)
        for triple in candidates:
            if (
                (s is None or triple[0] == s)
                and (p is None or triple[1] == p)
                and (o is None or triple[2] == o)
            ):
                yield triple, iter(_NO_CONTEXTS)

    def __len__(self, context: Any = None) -> int:
        return len(self.triples_held)

    def bind(self, prefix: str, namespace: Any, override: bool = True) -> None:
        if not override and namespace in self.names:
            return
        self.names.pop(self.prefixes.get(prefix), None)  # one name a prefix, one prefix a name
        self.prefixes.pop(self.names.get(namespace, ""), None)
        self.prefixes[prefix] = namespace
        self.names[namespace] = prefix

    def namespace(self, prefix: str) -> Any:
        return self.prefixes.get(prefix)

    def prefix(self, namespace: Any) -> str | None:
        return self.names.get(namespace)

    def namespaces(self) -> Iterator[tuple[str, Any]]:
        yield from self.prefixes.items()

    def contexts(self, triple: Triple | None = None) -> Generator[Graph, None, None]:
        yield from ()
