"""A large OWL Functional or Manchester document cut into documents of whole axioms or frames.

py-horned-owl holds the parse tree of a whole document: about 60 bytes for every byte of input
(100,000 class assertions, 2.7 MB, peaked at 166 MB), past the memory an input may cost
(issue 27: 50× the file or 100 MB).  Its RDF/XML is the same triples whether a document is read
at once or as pieces of whole top-level axioms (OFN) or frames (Manchester), each under the
document's own header, so a large one is read a piece at a time.  Each piece keeps every
byte of its part at the line and column it has in the file (the lines before it are blank),
so an error is placed in the file as the whole document would place it.  Anonymous individuals
(`_:x`) name one individual across axioms; a document using them is read whole.
"""

from __future__ import annotations

import re

PIECE = 1 << 19  # characters of axioms a piece holds, at least one axiom or frame

_OPAQUE = r'"(?:[^"\\]|\\.)*"|#[^\r\n]*|<[^<>\s]*>'
_OFN = re.compile(_OPAQUE + r"|(?P<name>\w+)?\s*\(|\)", re.S)  # an opening names its axiom
_FRAMES = (
    "Class|ObjectProperty|DataProperty|AnnotationProperty|Individual|Datatype|"
    "EquivalentClasses|DisjointClasses|EquivalentProperties|DisjointProperties|"
    "SameIndividual|DifferentIndividuals|Rule"
)
_OMN = re.compile(_OPAQUE + r"|(?m:^[ \t]*(?P<frame>" + _FRAMES + r"):(?=\s))", re.S)
_HEADER_ITEMS = ("Import", "Annotation")


def pieces(text: str, fmt: str) -> list[str]:
    """`text` as documents of about PIECE characters of axioms each (one, the text itself, when
    it is small, uses anonymous individuals, or is not shaped as expected: then py-horned-owl
    reads it whole and says what is wrong)."""
    size = PIECE
    if len(text) <= size or "_:" in text:
        return [text]
    found = _ofn_items(text) if fmt == "ofn" else _omn_frames(text) if fmt == "omn" else None
    if found is None or len(found) < 2:
        return [text]
    starts, close = found
    header = text[: starts[0]]
    cuts = [starts[0]]
    for start in starts:
        if start - cuts[-1] >= size:
            cuts.append(start)
    ends = [*cuts[1:], len(text)]
    return [
        header + _blank(text, starts[0], a) + text[a:b] + (close if b < len(text) else "")
        for a, b in zip(cuts, ends, strict=True)
    ]


def _blank(text: str, since: int, at: int) -> str:
    """What puts `at` of a piece at its line and column in the file: the lines from `since`
    blank, then spaces up to its column."""
    if at == since:
        return ""
    lines = text.count("\n", since, at)
    column = at - (text.rfind("\n", 0, at) + 1) if lines else at - since
    return "\n" * lines + " " * column


def _ofn_items(text: str) -> tuple[list[int], str] | None:
    """Where each top-level axiom inside `Ontology(` starts (past imports and annotations)."""
    depth, ontology, starts = 0, False, list[int]()
    for token in _OFN.finditer(text):
        mark = token.group()
        if mark.endswith("("):
            name = token.group("name")
            if depth == 0:
                ontology = ontology or name == "Ontology"
            elif depth == 1 and ontology:
                if name is None:
                    return None
                if not (name in _HEADER_ITEMS and not starts):
                    starts.append(token.start())
            depth += 1
        elif mark == ")":
            depth -= 1
            if depth < 0:
                return None
    return (starts, "\n)") if depth == 0 and ontology else None


def _omn_frames(text: str) -> tuple[list[int], str] | None:
    """Where each frame starts (`Class:`, `Individual:` …, at the start of a line)."""
    starts = [
        token.start("frame") for token in _OMN.finditer(text) if token.group("frame") is not None
    ]
    return (starts, "\n") if starts else None
