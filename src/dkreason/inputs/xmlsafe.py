"""Untrusted XML: refuse external entities and DTDs before any parser can open them.

Protégé writes internal `<!ENTITY>` declarations (the thesis ontologies use them), so those stay
allowed; expat (>= 2.4) refuses entity-expansion bombs itself with bounded memory.  Every XML
document — RDF/XML, SSL_T XML, COWL — passes `check` before it is parsed for meaning; OWL/XML
passes `standalone`, which also bounds its depth and resolves its DTD for py-horned-owl (which
reads no DTD).
"""

from __future__ import annotations

import pyexpat
import xml.etree.ElementTree as ET
from collections.abc import Callable
from typing import NamedTuple
from xml.sax.saxutils import escape, quoteattr

from ..errors import ParseError, Span


def _guarded(file: str, on_doctype: Callable[[], None] = lambda: None) -> pyexpat.XMLParserType:
    """A parser that refuses external DTDs and entities and never reads parameter entities
    (and calls `on_doctype` when a document type passes)."""
    parser = pyexpat.ParserCreate()

    def refuse(what: str) -> None:
        raise ParseError(
            f"{what} refused (external references are not followed)",
            Span(file, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1),
        )

    def doctype(name: str, system_id: str | None, public_id: str | None, _internal: int) -> None:
        if system_id or public_id:
            refuse(f"external DTD {system_id or public_id!r}")
        on_doctype()

    def entity(
        name: str,
        _is_param: int,
        _value: str | None,
        _base: str | None,
        system_id: str | None,
        public_id: str | None,
        _notation: str | None,
    ) -> None:
        if system_id or public_id:
            refuse(f"external entity {name!r} ({system_id or public_id})")

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.SetParamEntityParsing(pyexpat.XML_PARAM_ENTITY_PARSING_NEVER)
    return parser


def _parse(parser: pyexpat.XMLParserType, data: bytes, file: str) -> None:
    try:
        parser.Parse(data, True)
    except pyexpat.ExpatError as exc:
        raise ParseError(
            f"malformed XML: {pyexpat.ErrorString(exc.code)}",
            Span(file, exc.lineno, exc.offset + 1),
        ) from None


def check(data: bytes, file: str) -> None:
    """Raise ParseError if `data` is malformed or references anything outside itself."""
    _parse(_guarded(file), data, file)


def standalone(data: bytes, file: str, max_depth: int) -> bytes:
    """`data` checked (as `check`) and at most `max_depth` elements deep, as a document a
    reader that knows no DTD reads as expat does: when it has a document type, written again
    without it, its internal entities and default attributes in place."""
    depth = 0
    out: list[str] | None = None  # the document written again, once a DTD is seen

    def doctype() -> None:
        nonlocal out
        out = ['<?xml version="1.0" encoding="UTF-8"?>\n']

    parser = _guarded(file, doctype)

    def start(name: str, attributes: list[str]) -> None:
        nonlocal depth
        depth += 1
        if depth > max_depth:
            raise ParseError(
                f"malformed XML: elements nested deeper than {max_depth}",
                Span(file, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1),
            )
        if out is not None:
            pairs = zip(attributes[::2], attributes[1::2], strict=True)
            out.append(f"<{name}" + "".join(f" {k}={quoteattr(v)}" for k, v in pairs) + ">")

    def end(name: str) -> None:
        nonlocal depth
        depth -= 1
        if out is not None:
            out.append(f"</{name}>")

    def text(data: str) -> None:
        if out is not None:
            out.append(escape(data))

    parser.ordered_attributes = True
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    _parse(parser, data, file)
    return data if out is None else "".join(out).encode("utf-8")


class Extent(NamedTuple):
    """Where an element is: its first line, and byte offsets of its start tag's `<`, of its
    end tag's `<` (`close`; the end of an empty-element tag), and just past its end."""

    line: int
    start: int
    close: int
    end: int


def parse(data: bytes, file: str) -> tuple[ET.Element, dict[ET.Element, Extent]]:
    """Check, then parse; also return where each element is, so edits can touch only it."""
    check(data, file)
    parser = pyexpat.ParserCreate(namespace_separator="}")
    builder = ET.TreeBuilder()
    where: dict[ET.Element, Extent] = {}
    stack: list[tuple[ET.Element, int, int, bool]] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        elem = builder.start(_clark(tag), {_clark(k): v for k, v in attrs.items()})
        at = parser.CurrentByteIndex
        stack.append((elem, parser.CurrentLineNumber, at, _empty_tag(data, at)))

    def end(tag: str) -> None:
        builder.end(_clark(tag))
        elem, line, at, empty = stack.pop()
        close = parser.CurrentByteIndex
        stop = close if empty else data.index(b">", close) + 1
        where[elem] = Extent(line, at, close, stop)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    parser.Parse(data, True)
    return builder.close(), where


def _empty_tag(data: bytes, at: int) -> bool:
    """Whether the start tag at `at` is an empty-element tag (`<a …/>`); quotes may hold `>`."""
    quote = 0
    for i in range(at, len(data)):
        c = data[i]
        if quote:
            quote = 0 if c == quote else quote
        elif c in b"'\"":
            quote = c
        elif c == 0x3E:  # >
            return data[i - 1] == 0x2F  # /
    return False


def _clark(name: str) -> str:
    return "{" + name if "}" in name else name
