"""COWL bridge rules (thesis listings 3.1/3.2/6.5): `<cowl:bridgeRule cowl:br-type="…">`.

Plain XML, not RDF/XML.  Element names are matched by local name so files written with another
prefix, or for individuals (`sourceIndividual`), read the same.  Whether the named entities
exist is checked later against the two ontologies (kb.build), which also knows their kinds.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ParseError, Span
from ..inputs.files import read_bytes
from ..model import BRIDGE_TYPES, BridgeRule


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def read_bridge_rules(path: Path) -> tuple[BridgeRule, ...]:
    from ..inputs import xmlsafe

    file = str(path)
    root, where = xmlsafe.parse(read_bytes(path), file)
    if _local(root.tag) != "mapping":
        raise ParseError(
            f"root element is <{_local(root.tag)}>, expected <cowl:mapping>",
            Span(file, where[root][0]),
        )
    rules = []
    for n, elem in enumerate((e for e in root.iter() if _local(e.tag) == "bridgeRule"), 1):
        span = Span(file, where[elem][0])
        kind = next((v for k, v in elem.attrib.items() if _local(k) == "br-type"), None)
        if kind not in BRIDGE_TYPES:
            raise ParseError(
                f"bridge rule {n}: br-type {kind!r} is not one of {', '.join(BRIDGE_TYPES)}", span
            )
        ends: dict[str, str] = {}
        for child in elem:
            side = (
                "source"
                if _local(child.tag).startswith("source")
                else "target"
                if _local(child.tag).startswith("target")
                else None
            )
            resource = next((v for k, v in child.attrib.items() if _local(k) == "resource"), None)
            if side is None or not resource:
                raise ParseError(
                    f"bridge rule {n}: unexpected <{_local(child.tag)}>; expected "
                    f"sourceConcept/targetConcept with rdf:resource",
                    Span(file, where[child][0]),
                )
            if side in ends:
                raise ParseError(f"bridge rule {n}: two {side} entities", span)
            ends[side] = resource.strip()
        if len(ends) != 2:
            missing = "source" if "source" not in ends else "target"
            raise ParseError(f"bridge rule {n}: no {missing} entity", span)
        rules.append(BridgeRule(kind, ends["source"], ends["target"], span))
    return tuple(rules)
