"""Untrusted XML: refuse external entities and DTDs before any parser can open them.

Protégé writes internal `<!ENTITY>` declarations (the thesis ontologies use them), so those stay
allowed; expat (>= 2.4) refuses entity-expansion bombs itself with bounded memory.  Every XML
document — RDF/XML, SSL_T XML, COWL — passes `check` before it is parsed for meaning.
"""

from __future__ import annotations

import pyexpat
import xml.etree.ElementTree as ET

from .errors import ParseError, Span


def check(data: bytes, file: str) -> None:
    """Raise ParseError if `data` is malformed or references anything outside itself."""
    parser = pyexpat.ParserCreate()

    def refuse(what: str) -> None:
        raise ParseError(f"{what} refused (external references are not followed)",
                         Span(file, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1))

    def doctype(name: str, system_id: str | None, public_id: str | None, _internal: int) -> None:
        if system_id or public_id:
            refuse(f"external DTD {system_id or public_id!r}")

    def entity(name: str, _is_param: int, _value: str | None, _base: str | None,
               system_id: str | None, public_id: str | None, _notation: str | None) -> None:
        if system_id or public_id:
            refuse(f"external entity {name!r} ({system_id or public_id})")

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.SetParamEntityParsing(pyexpat.XML_PARAM_ENTITY_PARSING_NEVER)
    try:
        parser.Parse(data, True)
    except pyexpat.ExpatError as exc:
        raise ParseError(f"malformed XML: {pyexpat.ErrorString(exc.code)}",
                         Span(file, exc.lineno, exc.offset + 1)) from None


Lines = dict[ET.Element, tuple[int, int]]


def parse(data: bytes, file: str) -> tuple[ET.Element, Lines]:
    """Check, then parse; also return each element's first and last line."""
    check(data, file)
    parser = pyexpat.ParserCreate(namespace_separator="}")
    builder = ET.TreeBuilder()
    lines: Lines = {}
    stack: list[ET.Element] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        stack.append(builder.start(_clark(tag), {_clark(k): v for k, v in attrs.items()}))
        lines[stack[-1]] = (parser.CurrentLineNumber, parser.CurrentLineNumber)

    def end(tag: str) -> None:
        builder.end(_clark(tag))
        elem = stack.pop()
        lines[elem] = (lines[elem][0], parser.CurrentLineNumber)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    parser.Parse(data, True)
    return builder.close(), lines


def _clark(name: str) -> str:
    return "{" + name if "}" in name else name
