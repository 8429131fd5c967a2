"""Local names → IRIs, per platform, through an index (the thesis scanned the ontology instead).

A name may be written three ways wherever one may stand: `Heading` (local name, must be unique
among the platform's entities of the expected kind), `hr:Heading` (prefix declared in that
platform's ontology file) or `<http://…#Heading>`.  An IRI may be of several kinds (OWL 2
punning: `UAV` a class and an individual); it stands for the kind the place expects.
"""

from __future__ import annotations

import difflib
from collections import defaultdict
from collections.abc import Iterable, Mapping
from functools import lru_cache
from typing import Literal

from .errors import NameError_, Span

Kind = Literal["feature", "sort", "object", "property"]


@lru_cache(maxsize=1 << 16)  # requests name every matched topic's feature and objects
def local_name(iri: str) -> str:
    for sep in ("#", "/", ":"):
        if sep in iri:
            iri = iri.rsplit(sep, 1)[1] or iri
    return iri


class NameIndex:
    def __init__(
        self, platform: str, prefixes: Mapping[str, str], entities: Mapping[Kind, Iterable[str]]
    ) -> None:
        self.platform = platform
        self.prefixes = dict(prefixes)
        self._kinds: dict[str, set[Kind]] = defaultdict(set)
        self._by_local: dict[str, list[str]] = defaultdict(list)
        for kind, iris in entities.items():
            for iri in iris:
                if iri not in self._kinds:
                    self._by_local[local_name(iri)].append(iri)
                self._kinds[iri].add(kind)

    def kinds(self, iri: str) -> frozenset[Kind]:
        return frozenset(self._kinds.get(iri, ()))

    def lookup(self, written: str) -> list[str]:
        """The IRIs `written` may name here, of any kind: those with that local name, or a
        prefixed name's expansion (a prefix this platform declares)."""
        prefix, colon, rest = written.partition(":")
        if colon:
            return [self.prefixes[prefix] + rest] if prefix in self.prefixes else []
        return list(self._by_local.get(written, ()))

    def resolve(self, written: str, kinds: tuple[Kind, ...], span: Span) -> str:
        """The IRI `written` names among entities of `kinds`, or a NameError_ saying why not."""
        wanted = " or ".join(kinds)
        if written.startswith("<") and written.endswith(">"):
            candidates = [written[1:-1]]
        elif ":" in written:
            prefix, _, rest = written.partition(":")
            if prefix not in self.prefixes:
                raise NameError_(
                    f"unknown prefix {prefix!r} in {written!r} on {self.platform} "
                    f"(declared: {', '.join(sorted(self.prefixes)) or 'none'})",
                    span,
                )
            candidates = [self.prefixes[prefix] + rest]
        else:
            candidates = self._by_local.get(written, [])
        fitting = [iri for iri in candidates if self.kinds(iri) & set(kinds)]
        if len(fitting) == 1:
            return fitting[0]
        if len(fitting) > 1:
            both = " and ".join(f"<{iri}>" for iri in sorted(fitting))
            raise NameError_(
                f"ambiguous {wanted} {written!r} on {self.platform}: {both}; "
                f"write a prefixed name or a full <IRI>",
                span,
            )
        other = sorted(k for iri in candidates for k in self.kinds(iri))
        if other:
            raise NameError_(
                f"{written!r} is {article(other[0])} on {self.platform}, not {article(wanted)}",
                span,
            )
        known = [
            n for n, iris in self._by_local.items() if any(self.kinds(i) & set(kinds) for i in iris)
        ]
        close = difflib.get_close_matches(written, known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise NameError_(f"unknown {wanted} {written!r} on {self.platform}{hint}", span)


def article(noun: str) -> str:
    return f"{'an' if noun[0] in 'aeiou' else 'a'} {noun}"
