"""Untrusted XML: no external entities or DTDs, no entity bombs; internal entities allowed."""

from __future__ import annotations

import tracemalloc

import pytest

from dkreason.errors import ParseError
from dkreason.inputs import xmlsafe

from .conftest import entity_bomb


def test_internal_entities_as_protege_writes_them_are_fine() -> None:
    xmlsafe.check(b'<!DOCTYPE r [<!ENTITY o "http://x.org/o#">]><r a="&o;b"/>', "f.xml")


@pytest.mark.parametrize(
    "doc",
    [
        b'<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><r>&x;</r>',
        b'<!DOCTYPE r SYSTEM "http://example.com/evil.dtd"><r/>',
        b'<!DOCTYPE r PUBLIC "-//X//Y" "http://example.com/y.dtd"><r/>',
        b'<!DOCTYPE r [<!ENTITY % p SYSTEM "http://example.com/p.dtd"> %p;]><r/>',
    ],
)
def test_external_references_are_refused_without_opening_them(doc: bytes) -> None:
    with pytest.raises(ParseError, match="refused"):
        xmlsafe.check(doc, "f.xml")


def test_entity_bomb_is_refused_with_bounded_memory() -> None:
    bomb = entity_bomb("r").encode()
    tracemalloc.start()
    try:
        with pytest.raises(ParseError, match="amplification"):
            xmlsafe.check(bomb, "bomb.xml")
        assert tracemalloc.get_traced_memory()[1] < 10_000_000
    finally:
        tracemalloc.stop()
