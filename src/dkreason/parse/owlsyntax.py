"""Which syntax an ontology file is in, and OWL's own syntaxes read by py-horned-owl without
letting it take the process down.

py-horned-owl parses on the process's stack and writes RDF/XML indented by nesting: 10,000
nested class expressions overflow the stack (a segmentation fault, no message) and 3,000 make
180 MB of indentation.  So a document reaches it only when its nesting is at most MAX_DEPTH
(counted in one pass that reads strings, IRIs and comments as py-horned-owl does, counting
rather more than less); it is parsed from its text only (given text that is a path,
py-horned-owl opens that file); and its RDF/XML goes to a private temporary file that rdflib
reads as a stream, never held in memory.  The syntax sniffer is one forward pass too, over a
preamble of any length.
"""

from __future__ import annotations

import re
from array import array
from itertools import accumulate
from pathlib import Path

from ..errors import ParseError, Span
from ..inputs.files import decode

MAX_DEPTH = 64  # nested class expressions; real ontologies stay within about 10

SYNTAXES = {"xml", "trix", "turtle", "nt", "nquads", "trig", "n3", "json-ld"}
XML_SYNTAXES = {"xml", "trix", "owx"}
OWL_SYNTAXES = {"ofn": "OWL Functional Syntax", "omn": "Manchester Syntax", "owx": "OWL/XML"}
# Suffixes that say one syntax; any other (.owl, .rdf, .xml, none) is told by the content.
_BY_SUFFIX = {
    ".ttl": "turtle",
    ".nt": "nt",
    ".nq": "nquads",
    ".trig": "trig",
    ".n3": "n3",
    ".jsonld": "json-ld",
    ".json": "json-ld",
    ".trix": "trix",
    ".ofn": "ofn",
    ".omn": "omn",
    ".owx": "owx",
}
_BOM = b"\xef\xbb\xbf"


def syntax(data: bytes, file: str) -> str:
    """The syntax of an ontology file: by its suffix where that says one, else by what its
    first statement starts with (an `.owl` file is RDF/XML, OWL/XML, Functional or Manchester
    syntax), however long the comments and document type before it."""
    by_suffix = _BY_SUFFIX.get(Path(file).suffix.lower())
    if by_suffix:
        return by_suffix
    start = preamble_end(data)
    head = data[start : start + 4096]
    if re.match(rb"(Prefix|Ontology)\s*\(", head):
        return "ofn"
    if re.match(rb"(Prefix|Ontology|Class|ObjectProperty|Individual)\s*:", head):
        return "omn"
    if head.startswith(b"<"):
        root = re.match(rb"<\s*([\w.\-]+:)?([\w.\-]+)", head)
        name = root.group(2) if root else b""
        return "owx" if name == b"Ontology" else "trix" if name == b"TriX" else "xml"
    if head[:1] in (b"{", b"["):
        return "json-ld"
    return "turtle"  # Turtle reads N-Triples too


_SPACE = re.compile(rb"\s*")
_DOCTYPE_PLAIN = re.compile(rb"[^\"'\[\]<>]*")  # up to what a document type gives meaning


def preamble_end(data: bytes) -> int:
    """Where the first statement starts: past a BOM, space, `#` comments, an XML declaration
    or processing instructions, XML comments and a document type with its internal subset.
    One forward pass: every step consumes what it looks at."""
    at = len(_BOM) if data.startswith(_BOM) else 0
    while True:
        at = _SPACE.match(data, at).end()  # type: ignore[union-attr]  # \s* always matches
        if data.startswith(b"#", at):
            at = _past(data, b"\n", at)
        elif data.startswith(b"<?", at):
            at = _past(data, b"?>", at)
        elif data.startswith(b"<!--", at):
            at = _past(data, b"-->", at + 4)
        elif data.startswith(b"<!DOCTYPE", at):
            at = _doctype_end(data, at + 9)
        else:
            return at


def _past(data: bytes, end: bytes, at: int) -> int:
    found = data.find(end, at)
    return len(data) if found < 0 else found + len(end)


def _doctype_end(data: bytes, at: int) -> int:
    """Just past the `>` that ends a document type: quoted strings hold `>` and `]`, and the
    internal subset `[…]` holds declarations, comments and strings."""
    subset = False
    while at < len(data):
        at = _DOCTYPE_PLAIN.match(data, at).end()  # type: ignore[union-attr]  # * matches
        c = data[at : at + 1]
        if c in (b'"', b"'"):
            at = _past(data, c, at + 1)
        elif subset and data.startswith(b"<!--", at):
            at = _past(data, b"-->", at + 4)
        elif c == b">" and not subset:
            return at + 1
        else:  # `[` opens the subset, `]` closes it; a `<` or `>` inside it is a declaration's
            subset = c == b"[" or (subset and c != b"]")
            at += 1
    return at


# ---- nesting depth -------------------------------------------------------------------------

# A string, a comment, an IRI (in Manchester syntax its parentheses still count: `<` also opens
# a facet there, which an IRI-like run could hide), a parenthesis or brace, a comma, a word.
_OPAQUE = rb'"(?:[^"\\]|\\.)*"|#[^\r\n]*|<[^<>\s]*>'
_SKIPPED = re.compile(_OPAQUE, re.S)
_NOT_PARENS = bytes(c for c in range(256) if c not in b"()")
_STEPS = bytes.maketrans(b"()", b"\x01\xff")  # as signed bytes: +1, -1
# Manchester syntax nests without parentheses too: `p some q some B` is two levels deep.
_NESTING = {b"some", b"only", b"value", b"min", b"max", b"exactly", b"not", b"inverse", b"that"}
_FLAT = {b"and", b"or", b","}
_WORD = rb"[\w:.\-]+"
_PLAIN = (  # a word that is neither a keyword nor a number
    rb"(?!(?:" + b"|".join(sorted(_NESTING | _FLAT - {b","})) + rb"|\d+)(?![\w:.\-]))" + _WORD
)
_TOKEN = re.compile(  # a run of plain words is one token: a large ontology is mostly that
    rb"(?P<opaque>" + _OPAQUE + rb")|(?P<mark>[(){},])"
    rb"|(?P<run>(?:" + _PLAIN + rb"\s+)+" + _PLAIN + rb")|(?P<word>" + _WORD + rb")",
    re.S,
)


def _parentheses(data: bytes) -> tuple[int, int]:
    """(deepest, lowest) running count of OWL Functional Syntax's parentheses, outside strings,
    comments and IRIs, at C speed: what every document of a sane depth costs."""
    steps = _SKIPPED.sub(b"", data).translate(_STEPS, _NOT_PARENS)
    depths = list(accumulate(array("b", steps)))
    return max(depths, default=0), min(depths, default=0)


def nesting(data: bytes, fmt: str) -> tuple[int, int]:
    """(the deepest nesting of `data` in OWL Functional or Manchester syntax, capped at
    MAX_DEPTH + 1, the offset where it is first reached).  Parentheses and braces count, in
    Manchester syntax each restriction keyword of a chain too; strings and comments do not."""
    manchester = fmt == "omn"
    chains = [0]  # per open parenthesis: restriction keywords since the last `and`, `or`, `,`
    depth = deepest = where = 0  # open parentheses plus the keywords of their chains
    plain = False  # the last token was a name, IRI or string (two in a row end a chain)
    for token in _TOKEN.finditer(data):
        text, kind = token.group(), token.lastgroup
        first = text[:1]
        if kind == "opaque" and (first != b"<" or not manchester):
            plain = plain if first == b"#" else True
            continue
        opened, closed = (
            (text.count(b"(") + text.count(b"{"), text.count(b")") + text.count(b"}"))
            if kind != "word" and kind != "run"
            else (0, 0)
        )
        if kind == "run":  # two names in a row: whatever chain there was has ended
            if manchester:
                depth -= chains[-1]
                chains[-1] = 0
                plain = True
            continue
        if opened or closed:
            chains += [0] * opened
            depth += opened
            plain = first == b"<" or first in b")}"  # an IRI or a whole group
        elif not manchester or text.isdigit():
            continue
        elif text in _NESTING:
            chains[-1] += 1
            depth += 1
            plain = False
        else:
            if text in _FLAT or plain:
                depth -= chains[-1]
                chains[-1] = 0
            plain = text not in _FLAT
        if depth > deepest:
            deepest, where = depth, token.start()
            if deepest > MAX_DEPTH:
                break
        for _ in range(closed):  # after the opening ones: an IRI's `(…)` is as deep as it goes
            if len(chains) > 1:
                depth -= 1 + chains.pop()
    return deepest, where


def _position(data: bytes, offset: int) -> tuple[int, int]:
    before = data[:offset]
    return before.count(b"\n") + 1, len(before) - before.rfind(b"\n")


def check_depth(data: bytes, file: str, fmt: str) -> None:
    """Refuse, with its place, a document nested deeper than MAX_DEPTH."""
    if fmt == "ofn":
        deepest, lowest = _parentheses(data)
        if deepest <= MAX_DEPTH and lowest >= 0:
            return  # the common case, at C speed; else the token walk finds the place
    deepest, where = nesting(data, fmt)
    if deepest > MAX_DEPTH:
        raise ParseError(
            f"malformed {OWL_SYNTAXES[fmt]}: class expressions nested deeper than {MAX_DEPTH}",
            Span(file, *_position(data, where)),
        )


def owl_text(data: bytes, file: str, fmt: str) -> str:
    """The text of a document in OWL Functional, Manchester or OWL/XML syntax (already checked:
    no deeper than MAX_DEPTH, XML hardened), without a BOM; an empty or cut Manchester document
    is refused (py-horned-owl reads it as an empty ontology)."""
    text = decode(data, file).removeprefix("\ufeff")
    if fmt == "omn" and not re.search(r"(^|\s)Ontology:", text):
        raise ParseError(
            "malformed Manchester Syntax: no `Ontology:` header (an empty or cut file?)",
            Span(file),
        )
    return text


def write_rdf(text: str, file: str, fmt: str, out: Path) -> None:
    """Write the ontology in `text` (from `owl_text`, or a piece of one that keeps its lines and
    columns) to `out` as RDF/XML; an error names its place in `file`."""
    import pyhornedowl

    try:
        ontology = pyhornedowl.open_ontology_from_string(text, fmt)  # type: ignore[arg-type]
        ontology.save_to_file(str(out), "owl")
    except Exception as exc:  # its errors are ValueErrors that print a Rust debug dump
        message = str(exc)
        where = re.search(r"line_col: Pos\(\((\d+), (\d+)\)\)", message)
        offset = re.search(r"BytePosition\((\d+)\)", message)
        line = column = 0
        if where:
            line, column = int(where.group(1)), int(where.group(2))
        elif offset:
            line, column = _position(text.encode(), int(offset.group(1)))
        why = re.search(
            r"(ParserError|ValidityError|Error)\(\s*(\"[^\"]*\"|Error \{ "
            r"variant: \w+)",
            message,
        )
        shown = why.group(2).strip('"').replace("Error { variant: ", "") if why else "unreadable"
        raise ParseError(
            f"malformed {OWL_SYNTAXES[fmt]}: {shown}", Span(file, line, column)
        ) from None
