"""Untrusted XML: refuse external entities and DTDs before any parser can open them.

Protégé writes internal `<!ENTITY>` declarations (the thesis ontologies use them), so those stay
allowed; expat (>= 2.4) refuses entity-expansion bombs itself with bounded memory.  Every XML
document — RDF/XML, SSL_T XML, COWL — passes `check` before it is parsed for meaning.
"""

from __future__ import annotations

import pyexpat
import xml.etree.ElementTree as ET
from typing import NamedTuple

from ..errors import ParseError, Span


def check(data: bytes, file: str) -> None:
    """Raise ParseError if `data` is malformed or references anything outside itself."""
    parser = pyexpat.ParserCreate()

    def refuse(what: str) -> None:
        raise ParseError(
            f"{what} refused (external references are not followed)",
            Span(file, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1),
        )

    def doctype(name: str, system_id: str | None, public_id: str | None, _internal: int) -> None:
        if system_id or public_id:
            refuse(f"external DTD {system_id or public_id!r}")

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
    try:
        parser.Parse(data, True)
    except pyexpat.ExpatError as exc:
        raise ParseError(
            f"malformed XML: {pyexpat.ErrorString(exc.code)}",
            Span(file, exc.lineno, exc.offset + 1),
        ) from None


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
