"""OWL ontology (any RDF syntax rdflib reads) → `Ontology` of told axioms.

No OWL reasoning here: a feature's signature must come from its own asserted
`subClassOf (UnaryRelation ⊓ ∀arg1.S …)`, or GroundSpeed ≡ Speed would give both features both
signatures (thesis 6.1).  The closures the matcher needs are Datalog rules (rules/ontology.dl).
"""

from __future__ import annotations

import logging
import os
import re
import tempfile
import warnings
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span
from ..inputs.files import json_value, read_bytes, resolved
from ..model import IdValue, Ontology, Signature
from ..names import local_name
from .owlsplit import pieces
from .owlsyntax import (
    MAX_DEPTH,
    OWL_SYNTAXES,
    SYNTAXES,
    XML_SYNTAXES,
    check_depth,
    owl_text,
    syntax,
    write_rdf,
)

ARITY = {"UnaryRelation": 1, "BinaryRelation": 2, "TernaryRelation": 3}
ARG = re.compile(r"arg([1-9])$")
THING = "http://www.w3.org/2002/07/owl#Thing"


def read_ontology(path: Path, platform: str) -> Ontology:
    return parse_ontology(read_bytes(path), str(path), platform, resolved(path).as_uri())


@dataclass(frozen=True, slots=True)
class Sources:
    """An ontology's files with everything they import, merged into one graph: what was read
    and what was looked for but absent (every file and catalog, to tell when a cached model
    went stale) and what was skipped."""

    graph: Any
    read: tuple[tuple[Path, bytes], ...]
    skipped: tuple[str, ...]  # one warning line per import left out (imports = "skip")
    absent: tuple[Path, ...] = ()  # catalogs looked for and not found


def read_sources(
    files: Sequence[Path], imports: Mapping[str, Path] | None = None, skip: bool = False
) -> Sources:
    """The files, then what they import (`owl:imports`), each once however many import it
    (cycles included).  An import is found in `imports` (IRI → file, the config's
    `[imports]`), else in an OASIS XML catalog (`catalog-v001.xml`, as Protégé writes it)
    beside the importing file; nothing is fetched.  One that is found nowhere is an error
    naming the importing file and the IRI, or with `skip` a warning."""
    from rdflib import Graph, URIRef
    from rdflib.namespace import OWL, RDF

    from .triples import TripleStore

    graph: Any = None
    read: list[tuple[Path, bytes]] = []
    absent: list[Path] = []
    skipped: list[str] = []
    catalogs: dict[Path, dict[str, Path]] = {}
    loaded: set[Path] = set()
    names: set[str] = set()  # the ontologies loaded so far, by IRI without a trailing / or #
    prefixes: set[str] = set()
    todo: deque[tuple[Path, str | None]] = deque((Path(f), None) for f in files)
    while todo:
        path, iri = todo.popleft()
        where = resolved(path)
        if where in loaded:
            continue
        loaded.add(where)
        data = read_bytes(path)
        read.append((path, data))
        part = _graph(data, str(path), where.as_uri(), None)
        names |= {
            str(o).rstrip("/#")
            for o in part.subjects(RDF.type, OWL.Ontology)
            if isinstance(o, URIRef)
        }
        if iri:
            names.add(iri.rstrip("/#"))
        for _, _, wanted in sorted(part.triples((None, OWL.imports, None))):
            target = str(wanted)
            if target.rstrip("/#") in names:
                continue
            found = (imports or {}).get(target) or _catalog(
                path.parent, catalogs, read, absent
            ).get(target)
            if found is not None:
                todo.append((found, target))
                continue
            why = (
                f"owl:imports <{target}> is found neither in the config's [imports] nor in a "
                f"catalog-v001.xml beside it (nothing is fetched)"
            )
            if not skip:
                raise ParseError(why, Span(str(path)))
            skipped.append(f"{path}: {why}; skipped")
        if graph is None:  # the first file's graph is the merged one: not held twice
            graph = part
            prefixes = {prefix for prefix, _ in part.namespaces() if prefix}
            continue
        graph += part
        for prefix, ns in part.namespaces():
            if prefix and prefix not in prefixes:
                prefixes.add(prefix)
                graph.bind(prefix, ns)
        del part
    return Sources(
        Graph(store=TripleStore(), bind_namespaces="none") if graph is None else graph,
        tuple(read),
        tuple(skipped),
        tuple(absent),
    )


_XML_BASE = "{http://www.w3.org/XML/1998/namespace}base"


def _catalog(
    folder: Path,
    catalogs: dict[Path, dict[str, Path]],
    read: list[tuple[Path, bytes]],
    absent: list[Path],
) -> dict[str, Path]:
    """IRI → file of the catalog-v001.xml in `folder`, read once through the input door (none:
    empty, and noted as absent, so one that appears later is read).  Each `uri` is resolved
    as XML Base says, against the nearest `xml:base` and the catalog's own place; only a
    `file:` URI or a path names a file (nothing is fetched)."""
    if folder not in catalogs:
        path = folder / "catalog-v001.xml"
        found: dict[str, Path] = {}
        catalogs[folder] = found
        if not os.path.lexists(path):
            absent.append(path)
            return found
        from urllib.parse import urljoin, urlsplit
        from urllib.request import url2pathname

        from ..inputs import xmlsafe

        data = read_bytes(path)
        read.append((path, data))
        root, _ = xmlsafe.parse(data, str(path))
        todo = [(root, Path(os.path.abspath(path)).as_uri())]
        while todo:
            element, base = todo.pop()
            base = urljoin(base, element.get(_XML_BASE, ""))
            name, uri = element.get("name"), element.get("uri")
            if element.tag.rsplit("}", 1)[-1] == "uri" and name and uri:
                target = urlsplit(urljoin(base, uri))
                if target.scheme == "file" and target.netloc in ("", "localhost"):
                    found[name] = Path(url2pathname(target.path))
            todo.extend((child, base) for child in reversed(element))  # in document order
    return catalogs[folder]


def served(
    files: Sequence[Path], imports: Mapping[str, Path] | None = None, skip: bool = False
) -> tuple[str, str]:
    """A platform's ontology as its live node serves it: every file and import merged, as
    Turtle (a peer never chooses the parser its monitor runs, nor follows imports), and the
    SHA-256 of what was read (what tells a returning platform's ontology from the one it
    served before)."""
    import hashlib

    sources = read_sources(files, imports, skip)
    digest = hashlib.sha256()
    for path, data in sources.read:
        digest.update(str(path).encode() + b"\0" + data)
    return sources.graph.serialize(format="turtle"), digest.hexdigest()


def _graph(data: bytes, file: str, base: str | None, fmt: str | None) -> Any:
    """The RDF graph of `data`, in `fmt` or the syntax its name or content says; nothing
    outside `data` is ever read: XML passes the XML hardening, JSON-LD may not name a remote
    context, and OWL's own syntaxes are read by py-horned-owl into RDF/XML first
    (parse/owlsyntax.py: bounded nesting, read from their text only)."""
    fmt = fmt or syntax(data, file)
    if fmt not in SYNTAXES and fmt not in OWL_SYNTAXES:
        raise ParseError(
            f"syntax {fmt!r} is not read (use RDF/XML, Turtle, N-Triples, "
            f"N-Quads, TriG, TriX, N3, JSON-LD, OWL/XML, OWL Functional or "
            f"Manchester syntax)",
            Span(file),
        )
    from ..inputs import xmlsafe

    if fmt == "owx":
        data = xmlsafe.standalone(data, file, MAX_DEPTH)
    elif fmt in OWL_SYNTAXES:
        check_depth(data, file, fmt)
    elif fmt in XML_SYNTAXES:
        xmlsafe.check(data, file)
    elif fmt == "json-ld":
        _local_contexts(json_value(data, Span(file)), file)
    if fmt not in OWL_SYNTAXES:
        return _rdf(file, base, None, data=data, format=fmt)
    graph = None
    with tempfile.TemporaryDirectory(prefix="dkreason-owl-") as folder:
        rdf = Path(folder) / "ontology.owl"
        for piece in pieces(owl_text(data, file, fmt), fmt):  # owlsplit.py: memory bounded
            write_rdf(piece, file, fmt, rdf)
            graph = _rdf(file, base, graph, source=str(rdf), format="xml")
    return graph


def _rdf(file: str, base: str | None, graph: Any, **what: Any) -> Any:
    """rdflib's graph of `what` (data or a source, and a format), or `graph` with it added;
    `file` names it in errors.  JSON-LD's parser asks for a store of named graphs (rdflib's
    own); every other syntax is read into the compact one (parse/triples.py)."""
    from rdflib import Graph

    from .triples import TripleStore

    if graph is None:
        store = "default" if what["format"] == "json-ld" else TripleStore()
        graph = Graph(store=store, bind_namespaces="none")

    quiet = logging.getLogger("rdflib.term")  # ill-typed literals: reported by us, once
    quiet.disabled = True
    try:
        with warnings.catch_warnings():  # rdflib's own deprecations are not the user's concern
            warnings.simplefilter("ignore", DeprecationWarning)
            graph.parse(publicID=base, **what)
    except RecursionError:
        raise ParseError("malformed RDF: nested too deeply", Span(file)) from None
    except Exception as exc:  # rdflib raises many types; all mean "this file is not RDF"
        raise _rdf_error(exc, file) from None
    finally:
        quiet.disabled = False
    return graph


def _local_contexts(doc: Any, file: str) -> None:
    """Refuse a JSON-LD document whose @context or @import names anything to fetch."""
    todo = [doc]
    while todo:
        node = todo.pop()
        if isinstance(node, dict):
            for key, value in node.items():
                if key in ("@context", "@import") and (
                    isinstance(value, str)
                    or isinstance(value, list)
                    and any(isinstance(v, str) for v in value)
                ):
                    shown = (
                        value
                        if isinstance(value, str)
                        else next(v for v in value if isinstance(v, str))
                    )
                    raise ParseError(
                        f"JSON-LD context {shown[:100]!r} refused (external "
                        f"references are not followed)",
                        Span(file),
                    )
                todo.append(value)
        elif isinstance(node, list):
            todo.extend(node)


def parse_ontology(
    data: bytes, file: str, platform: str, base: str | None = None, fmt: str | None = None
) -> Ontology:
    """`file` names the data in messages and, unless `fmt` is given, tells its RDF syntax
    by its suffix.  Imports are not followed (a served ontology arrives merged)."""
    return ontology_of(_graph(data, file, base, fmt), file, platform)


def ontology_of(graph: Any, file: str, platform: str) -> Ontology:
    """The told axioms of an RDF graph; `file` names it in messages."""
    from rdflib import BNode, Literal, URIRef
    from rdflib.collection import Collection
    from rdflib.namespace import OWL, RDF, RDFS

    def named(node: object) -> bool:
        return isinstance(node, URIRef)

    def members(node: object) -> list[object]:
        return list(Collection(graph, node)) if isinstance(node, BNode) else []

    # OWL 2 declarations of what is not an object: properties (whatever their other
    # characteristics), datatypes, ontologies; their subjects are never objects (unless also
    # declared individuals: punning) and their types never sorts.
    declared_not_objects = {
        OWL.ObjectProperty,
        OWL.DatatypeProperty,
        OWL.AnnotationProperty,
        RDF.Property,
        OWL.OntologyProperty,
        OWL.TransitiveProperty,
        OWL.SymmetricProperty,
        OWL.AsymmetricProperty,
        OWL.ReflexiveProperty,
        OWL.IrreflexiveProperty,
        OWL.FunctionalProperty,
        OWL.InverseFunctionalProperty,
        OWL.DeprecatedProperty,
        RDFS.Datatype,
        OWL.DataRange,
        OWL.Ontology,
    }
    meta = {
        OWL.Class,
        RDFS.Class,
        OWL.NamedIndividual,
        OWL.Restriction,
        OWL.DeprecatedClass,
        OWL.AllDisjointClasses,
        OWL.AllDifferent,
        OWL.AllDisjointProperties,
        OWL.Axiom,
        OWL.NegativePropertyAssertion,
        *declared_not_objects,
    }
    not_objects = {s for t in declared_not_objects for s in graph.subjects(RDF.type, t)}
    classes = {s for s in graph.subjects(RDF.type, OWL.Class) if named(s)}
    classes |= {s for s in graph.subjects(RDF.type, RDFS.Class) if named(s)}
    for pred in (RDFS.subClassOf, OWL.equivalentClass):
        for s, o in graph.subject_objects(pred):
            classes |= {n for n in (s, o) if named(n)}
    declared = {s for s in graph.subjects(RDF.type, OWL.NamedIndividual) if named(s)}
    typed = [
        (s, o)
        for s, o in graph.subject_objects(RDF.type)
        if named(s) and named(o) and o not in meta and (s not in not_objects or s in declared)
    ]
    classes |= {o for _, o in typed}
    classes.add(URIRef(THING))

    features: dict[str, Signature] = {}
    for cls, sup in graph.subject_objects(RDFS.subClassOf):
        if not named(cls):
            continue
        parts = members(graph.value(sup, OWL.intersectionOf)) if isinstance(sup, BNode) else []
        arity = next(
            (ARITY[local_name(str(p))] for p in parts if named(p) and local_name(str(p)) in ARITY),
            None,
        )
        if arity is None:
            continue
        sorts: dict[int, tuple[str, ...]] = {}
        for part in parts:
            if not isinstance(part, BNode):
                continue
            prop, filler = graph.value(part, OWL.onProperty), graph.value(part, OWL.allValuesFrom)
            match = ARG.search(str(prop)) if prop is not None else None
            if match is None or filler is None:
                continue
            index = int(match.group(1))
            if index > arity:
                raise ParseError(
                    f"feature <{cls}> restricts arg{index} but is a {arity}-ary relation",
                    Span(file),
                )
            union = members(graph.value(filler, OWL.unionOf))
            sorts[index] = tuple(str(u) for u in union if named(u)) if union else (str(filler),)
        if str(cls) in features:
            raise ParseError(f"feature <{cls}> has two relation signatures", Span(file))
        features[str(cls)] = Signature(
            str(cls), tuple(sorts.get(i, (THING,)) for i in range(1, arity + 1))
        )

    individuals = declared | {s for s, _ in typed if s not in classes}
    same = [(str(a), str(b)) for a, b in graph.subject_objects(OWL.sameAs) if named(a) and named(b)]
    individuals |= {URIRef(x) for pair in same for x in pair}

    ids: dict[str, IdValue] = {}
    for ind in individuals:
        values = {
            o
            for p, o in graph.predicate_objects(ind)
            if isinstance(o, Literal) and local_name(str(p)) == "id"
        }
        if len(values) > 1:
            shown = ", ".join(sorted(str(v) for v in values))
            raise ParseError(f"object <{ind}> has several id values ({shown})", Span(file))
        if values:
            (lit,) = values
            if lit.ill_typed:
                raise ParseError(
                    f"object <{ind}>: id {str(lit)[:40]!r} is not a valid "
                    f"{local_name(str(lit.datatype))}",
                    Span(file),
                )
            value = lit.toPython()
            ids[str(ind)] = (
                value if isinstance(value, int) and not isinstance(value, bool) else str(lit)
            )

    told = _property_values(graph, individuals)
    return Ontology(
        platform=platform,
        file=file,
        classes=frozenset(str(c) for c in classes),
        features=features,
        subclass_of=tuple(
            sorted(
                (str(s), str(o))
                for s, o in graph.subject_objects(RDFS.subClassOf)
                if named(s) and named(o)
            )
        ),
        equivalent=tuple(
            sorted(
                (str(s), str(o))
                for s, o in graph.subject_objects(OWL.equivalentClass)
                if named(s) and named(o)
            )
        ),
        individuals=frozenset(str(i) for i in individuals),
        types=tuple(sorted((str(s), str(o)) for s, o in typed if s in individuals)),
        same_as=tuple(sorted(same)),
        ids=ids,
        prefixes={p: str(ns) for p, ns in graph.namespaces() if p},
        data_values=tuple(
            sorted(
                (
                    (str(s), p, _plain(o))
                    for s, pairs in told.items()
                    for p, o in pairs
                    if isinstance(o, Literal)
                ),
                key=str,
            )
        ),
        object_values=tuple(
            sorted(
                (str(s), p, str(o))
                for s, pairs in told.items()
                for p, o in pairs
                if not isinstance(o, Literal) and o in individuals
            )
        ),
    )


def triples(graph: Any) -> list[tuple[IdValue, IdValue, IdValue]]:
    """Every triple of a graph as adapter rules read it (rules/adapters/schema.dl): an IRI as
    such, a blank node as '_:' and its id, a literal as a fact holds it."""
    from rdflib import BNode, Literal

    def term(node: Any) -> IdValue:
        if isinstance(node, Literal):
            return _plain(node)
        return f"_:{node}" if isinstance(node, BNode) else str(node)

    return [(term(s), term(p), term(o)) for s, p, o in graph]


_BUILT_IN = (
    "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "http://www.w3.org/2000/01/rdf-schema#",
    "http://www.w3.org/2002/07/owl#",
)


def _property_values(graph: Any, individuals: set[Any]) -> dict[Any, list[tuple[str, Any]]]:
    """Each object's property assertions as told: (property IRI, literal or named object);
    RDF, RDFS and OWL's own vocabulary and annotation properties are not properties of it."""
    from rdflib import Literal, URIRef
    from rdflib.namespace import OWL, RDF

    annotations = set(graph.subjects(RDF.type, OWL.AnnotationProperty))
    out: dict[Any, list[tuple[str, Any]]] = {}
    for ind in individuals:
        pairs = [
            (str(p), o)
            for p, o in graph.predicate_objects(ind)
            if isinstance(p, URIRef)
            and not str(p).startswith(_BUILT_IN)
            and p not in annotations
            and isinstance(o, Literal | URIRef)
        ]
        if pairs:
            out[ind] = pairs
    return out


def _plain(lit: Any) -> IdValue:
    """A literal as a fact holds it: a whole number as a number, anything else as written."""
    value = lit.toPython()
    return value if isinstance(value, int) and not isinstance(value, bool) else str(lit)


def _rdf_error(exc: Exception, file: str) -> DkError:
    """rdflib's errors carry positions in different places; find one, keep one line."""
    line = column = 0
    text = (str(getattr(exc, "_why", "")) or str(exc)).strip()
    if hasattr(exc, "lines"):  # Turtle/N3 BadSyntax
        line = int(exc.lines) + 1
    where = re.match(r"\S*?:(\d+):(\d+): (.*)", text, re.S)  # RDF/XML "file:line:col: why"
    if where:
        line, column, text = int(where.group(1)), int(where.group(2)) + 1, where.group(3)
    first = text.splitlines()[0] if text else type(exc).__name__
    return ParseError(f"malformed RDF: {first}", Span(file, line, column))
