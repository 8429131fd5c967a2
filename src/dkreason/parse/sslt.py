"""SSL_T topic specifications: text (thesis listing 4.2) and XML (listing 4.5/4.6), both ways.

Text → XML → text keeps every topic, feature, argument kind, name and field; aliases exist in
text only (XML arguments are positional), so the writer invents `argN` aliases exactly where a
name repeats within one feature and binding by name would be ambiguous to a reader.
"""

from __future__ import annotations

import re
from contextvars import ContextVar
from dataclasses import dataclass, replace
from fractions import Fraction
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple, Protocol
from xml.sax.saxutils import quoteattr

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput

from ..errors import DkError, ParseError, Span
from ..inputs.files import decode, read_bytes
from ..inputs.numbers import decimal, duration, exact
from ..model import ArgKind, TopicArg, TopicFeature, TopicSpec
from .grammar import lalr


@cache
def _parser() -> Lark:
    # The transformer runs inside the LALR parser (no parse tree): spans come from tokens.
    # Built on first use (a specs file the cache does not hold), its tables from the cache.
    return lalr("sslt.lark", _ToModel())


@dataclass(frozen=True, slots=True)
class SpecFile:
    """Specs with the source extent each came from (character offsets in text, byte offsets
    in XML), so an edit touches only its own topic whatever the layout and line ends; `tail`
    is where a new topic goes (before `</Topic_specs>` in XML, the end of a text)."""

    specs: tuple[TopicSpec, ...]
    extents: tuple[tuple[int, int], ...]
    tail: int


# ---- text ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Entry:
    kind: ArgKind
    name: str
    field: str
    span: Span
    end: int  # offset just past the entry


@dataclass(frozen=True, slots=True)
class _Arg:
    name: str
    alias: str | None
    span: Span


@dataclass(frozen=True, slots=True)
class _Feature:
    name: str
    args: tuple[_Arg, ...]
    field: str
    span: Span
    end: int  # offset just past the feature's field
    observations: bool = False  # `observations of NAME`: name is a sensor's


class _Quality(NamedTuple):
    rate: Fraction | None
    delay: Fraction | None


_FILE: ContextVar[str] = ContextVar("sslt_file", default="<sslt>")  # the file being parsed


def _span(token: Token) -> Span:
    return Span(_FILE.get(), token.line or 0, token.column or 0)


class _ToModel(Transformer[Token, Any]):
    def name(self, children: list[Token]) -> Token:
        return children[0]

    def topic_name(self, children: list[Token]) -> str:
        token = children[0]
        if token.type == "ROSNAME":
            return str(token)
        text = re.sub(r"\\(.)", r"\1", str(token)[1:-1])
        if not text:
            raise ParseError("an empty topic name", _span(token))
        return text

    def quality_item(self, children: list[Token]) -> tuple[str, Fraction, Span]:
        name, value = children
        if name not in QUALITIES:
            raise ParseError(
                f"unknown stream property {str(name)!r} (a topic declares "
                f"{' and '.join(QUALITIES)})",
                _span(name),
            )
        return (str(name), quality_value(str(name), str(value), _span(value)), _span(name))

    def quality(self, children: list[tuple[str, Fraction, Span]]) -> _Quality:
        return _Quality(*quality_of(children))

    def arg(self, children: list[Any]) -> _Arg:
        return _Arg(
            str(children[0]), str(children[1]) if len(children) > 1 else None, _span(children[0])
        )

    def sort_entry(self, children: list[Any]) -> _Entry:
        kind, name, field = children
        return _Entry(
            str(kind),  # type: ignore[arg-type]
            str(name),
            str(field),
            _span(kind),
            field.end_pos or 0,
        )

    def object_entry(self, children: list[Any]) -> _Entry:
        name, field = children
        return _Entry("object", str(name), str(field), _span(name), field.end_pos or 0)

    def feature(self, children: list[Any]) -> list[Any]:
        name, *rest = children
        args = tuple(c for c in rest if isinstance(c, _Arg))
        field = next(c for c in rest if isinstance(c, Token))
        entries = [c for c in rest if isinstance(c, _Entry)]
        return [_Feature(str(name), args, str(field), _span(name), field.end_pos or 0), *entries]

    def observations(self, children: list[Any]) -> list[Any]:
        name, field = children
        return [_Feature(str(name), (), str(field), _span(name), field.end_pos or 0, True)]

    def topic(self, children: list[Any]) -> tuple[TopicSpec, int, int]:
        keyword, name, msgtype, *items = children
        quality = items.pop(0) if isinstance(items[0], _Quality) else _Quality(None, None)
        flat = [x for item in items for x in (item if isinstance(item, list) else [item])]
        span, lines = _span(keyword), (keyword.start_pos or 0, max(x.end for x in flat))
        if isinstance(flat[0], _Entry):
            if len(flat) > 1:
                raise ParseError(
                    f"topic {name} lists {len(flat)} entities; a sort or object "
                    f"topic carries exactly one",
                    span,
                )
            entry = flat[0]
            entity = TopicArg(entry.kind, entry.name, entry.field, entry.span)
            return (
                TopicSpec(str(name), str(msgtype), (), entity, span, *quality),
                *lines,
            )
        features: list[TopicFeature] = []
        pending: list[_Entry] = []
        current: _Feature | None = None
        for x in [*flat, None]:
            if isinstance(x, _Entry):
                pending.append(x)
                continue
            if current is not None:
                features.append(_bind(current, pending))
            current, pending = x, []
        return (
            TopicSpec(str(name), str(msgtype), tuple(features), None, span, *quality),
            *lines,
        )


def _bind(feature: _Feature, entries: list[_Entry]) -> TopicFeature:
    """Bind `for` entries to arguments: by alias, else the first unbound argument of that name."""
    bound: dict[int, _Entry] = {}
    for entry in entries:
        slot = next((i for i, a in enumerate(feature.args) if a.alias == entry.name), None)
        if slot is None:
            slot = next(
                (
                    i
                    for i, a in enumerate(feature.args)
                    if a.name == entry.name and a.alias is None and i not in bound
                ),
                None,
            )
        if slot is None:
            raise ParseError(
                f"'for {entry.name}' names no unbound argument of {feature.name}", entry.span
            )
        if slot in bound:
            raise ParseError(f"argument {slot + 1} of {feature.name} bound twice", entry.span)
        bound[slot] = entry
    args = []
    for i, a in enumerate(feature.args):
        found = bound.get(i)
        args.append(
            TopicArg(found.kind, a.name, found.field, a.span)
            if found
            else TopicArg("object", a.name, None, a.span)
        )
    return TopicFeature(
        feature.name, feature.field, tuple(args), feature.span, feature.observations
    )


QUALITIES = ("rate", "delay")
_RATE = re.compile(r"(.*?)\s*(hz)?", re.I)


def quality_value(name: str, text: str, span: Span) -> Fraction:
    """A declared stream property (one of QUALITIES) from its text: `rate` in Hz (`20 Hz`,
    `0.5Hz`, `20`), positive; `delay` a duration as formulas write it (`50ms`, `0.05`)."""
    text = text.strip()
    try:
        if name == "delay":
            return duration(text, "delay")
        rate = exact(_RATE.fullmatch(text).group(1), "rate")  # type: ignore[union-attr]
    except DkError:
        what = "a rate in Hz, like 20 Hz" if name == "rate" else "a duration, like 50ms"
        raise ParseError(f"{name} {text!r} is not {what}", span) from None
    if rate <= 0:
        raise ParseError(f"rate {text!r} must be positive", span)
    return rate


def quality_of(items: list[tuple[str, Fraction, Span]]) -> tuple[Fraction | None, ...]:
    """(rate, delay) from the declared properties, each at most once."""
    found: dict[str, Fraction] = {}
    for name, value, span in items:
        if name in found:
            raise ParseError(f"{name} is declared twice", span)
        found[name] = value
    return tuple(found.get(q) for q in QUALITIES)


class Declares(Protocol):
    """What declares a stream's quality: a spec, or what carries a spec's (info's bindings)."""

    @property
    def rate(self) -> Fraction | None: ...
    @property
    def delay(self) -> Fraction | None: ...


def format_quality(spec: Declares) -> list[tuple[str, str]]:
    """The declared properties as SSL_T and XML write them: (name, value text)."""
    out = []
    if spec.rate is not None:
        out.append(("rate", f"{decimal(spec.rate)} Hz"))
    if spec.delay is not None:
        ms = spec.delay * 1000
        out.append(("delay", f"{decimal(ms)}ms" if ms < 1000 else f"{decimal(spec.delay)}s"))
    return out


def parse_text(text: str, file: str = "<sslt>") -> SpecFile:
    token = _FILE.set(file)
    try:
        rows: list[tuple[TopicSpec, int, int]] = _parser().parse(text).children  # type: ignore[assignment]
    except UnexpectedInput as exc:
        raise _syntax_error(exc, file) from None
    finally:
        _FILE.reset(token)
    specs = tuple(spec for spec, _, _ in rows)
    _no_duplicates(specs)
    return SpecFile(specs, tuple((first, last) for _, first, last in rows), len(text))


def _syntax_error(exc: UnexpectedInput, file: str) -> ParseError:
    span = Span(file, getattr(exc, "line", 0) or 0, getattr(exc, "column", 0) or 0)
    expected = sorted(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or ())
    wanted = ", ".join(_TERMINALS.get(e.lstrip("_"), e.lstrip("_").lower()) for e in expected[:8])
    if isinstance(exc, UnexpectedEOF):
        return ParseError(f"syntax error: unexpected end of input, expected {wanted}", span)
    if isinstance(exc, UnexpectedCharacters):
        return ParseError(
            f"syntax error: unexpected character {exc.char!r}"
            + (f", expected {wanted}" if wanted else ""),
            span,
        )
    last = (getattr(getattr(exc, "state", None), "value_stack", None) or [None])[-1]
    if "RSQB" in expected and isinstance(last, Token) and last.type == "QUALITY_VALUE":
        # the bracket of stream properties left open: where its `]` belongs
        where = Span(file, last.line or 0, (last.column or 0) + len(last.rstrip()))
        return ParseError("missing ']' after the stream properties", where)
    token = getattr(exc, "token", None)
    return ParseError(f"syntax error: unexpected {str(token)!r}, expected {wanted}", span)


_TERMINALS = {
    "NAME": "a name",
    "PNAME": "a prefixed name",
    "IRI": "an <IRI>",
    "FIELD": "a message field like msg.id",
    "SORT_TYPE": "'some' or 'every'",
    "COMMA": "','",
    "EQUAL": "'='",
    "LPAR": "'('",
    "RPAR": "')'",
    "COLON": "':'",
    "TOPIC": "'topic'",
    "CONTAINS": "'contains'",
    "FOR": "'for'",
    "AS": "'as'",
    "SORT": "'sort'",
    "OBSERVATIONS": "'observations of'",
    "LSQB": "'['",
    "RSQB": "']'",
    "QUALITY_VALUE": "a value, like 20 Hz or 50ms",
    "$END": "end of input",
}


def _no_duplicates(specs: tuple[TopicSpec, ...]) -> None:
    seen: dict[str, TopicSpec] = {}
    for spec in specs:
        if spec.name in seen:
            raise ParseError(
                f"topic {spec.name} is specified twice (first at line {seen[spec.name].span.line})",
                spec.span,
            )
        seen[spec.name] = spec


_ROS_NAME = re.compile(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


def topic_name_text(name: str) -> str:
    """A topic name as SSL_T writes it: a ROS name as it is, any other name quoted."""
    if _ROS_NAME.fullmatch(name):
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def format_spec(spec: TopicSpec) -> str:
    """One line of SSL_T text for `spec` (the inverse of `parse_text`)."""
    quality = ", ".join(f"{name} {value}" for name, value in format_quality(spec))
    bracket = f" [{quality}]" if quality else ""
    head = f"topic {topic_name_text(spec.name)}:{spec.msgtype}{bracket} contains "
    if spec.entity is not None:
        e = spec.entity
        return head + (
            f"{e.name} = {e.id_field}"
            if e.kind == "object"
            else f"{e.kind} {e.name} = {e.id_field}"
        )
    parts = []
    for f in spec.features:
        if f.observations:
            parts.append(f"observations of {f.name} = {f.field}")
            continue
        repeated = {a.name for a in f.args if sum(b.name == a.name for b in f.args) > 1}
        labels = [f"arg{i + 1}" if a.name in repeated else a.name for i, a in enumerate(f.args)]
        args = ", ".join(
            f"{a.name} as {lab}" if a.name in repeated else a.name
            for a, lab in zip(f.args, labels, strict=True)
        )
        entries = [
            (f"{lab} = {a.id_field}" if a.kind == "object" else f"{a.kind} {lab} = {a.id_field}")
            for a, lab in zip(f.args, labels, strict=True)
            if a.id_field is not None
        ]
        parts.append(
            f"{f.name}({args}) = {f.field}" + (f" for {', '.join(entries)}" if entries else "")
        )
    return head + ", ".join(parts)


# ---- XML (DTD of listing 4.5, cleaned: specs/topic_specs.dtd) ------------------------------


def parse_xml(data: bytes, file: str = "<xml>") -> SpecFile:
    from ..inputs import xmlsafe

    root, where = xmlsafe.parse(data, file)

    def span(elem: Any) -> Span:
        return Span(file, where[elem].line if elem in where else 0)

    if root.tag != "Topic_specs":
        raise ParseError(f"root element is <{root.tag}>, expected <Topic_specs>", span(root))
    specs, extents = [], []
    for topic in root:
        tspan = span(topic)
        if topic.tag != "Topic":
            raise ParseError(f"unexpected <{topic.tag}> in <Topic_specs>", tspan)
        name, msgtype = _attr(topic, "name", tspan), _attr(topic, "msgtype", tspan)
        children = [c for c in topic if c.tag != "SSL"]
        features = []
        for child in children:
            cspan = span(child)
            if child.tag == "feature":
                args = tuple(_xml_arg(a, span(a), in_feature=True) for a in child)
                if not args:
                    raise ParseError(
                        f"feature {_attr(child, 'name', cspan)} in topic {name} has no arguments",
                        cspan,
                    )
                features.append(
                    TopicFeature(
                        _attr(child, "name", cspan), _attr(child, "value", cspan), args, cspan
                    )
                )
            elif child.tag == "observations":
                features.append(
                    TopicFeature(
                        _attr(child, "sensor", cspan), _attr(child, "value", cspan), (), cspan, True
                    )
                )
            elif child.tag not in ("sort", "object"):
                raise ParseError(f"unexpected <{child.tag}> in topic {name}", cspan)
        if features and len(features) != len(children):
            raise ParseError(f"topic {name} mixes features with a sort or object", tspan)
        if not features and len(children) != 1:
            raise ParseError(f"topic {name} must hold features, or one sort, or one object", tspan)
        entity = None if features else _xml_arg(children[0], span(children[0]), in_feature=False)
        quality = quality_of(
            [
                (q, quality_value(q, value, tspan), tspan)
                for q in QUALITIES
                if (value := topic.get(q)) is not None
            ]
        )
        specs.append(TopicSpec(name, msgtype, tuple(features), entity, tspan, *quality))
        extents.append((where[topic].start, where[topic].end))
    out = tuple(specs)
    _no_duplicates(out)
    return SpecFile(out, tuple(extents), where[root].close)


def _attr(elem: Any, name: str, span: Span) -> str:
    value = elem.get(name)
    if value is None or not value.strip():
        raise ParseError(f"<{elem.tag}> lacks the {name!r} attribute", span)
    return str(value).strip()


def _xml_arg(elem: Any, span: Span, *, in_feature: bool) -> TopicArg:
    if elem.tag == "object":
        value = elem.get("value")
        if value is None and not in_feature:
            raise ParseError("an object topic needs the object's id field (value)", span)
        return TopicArg("object", _attr(elem, "name", span), value, span)
    if elem.tag == "sort":
        every = _attr(elem, "all_objects", span)
        if every not in ("true", "false"):
            raise ParseError(f"all_objects must be true or false, not {every!r}", span)
        return TopicArg(
            "every" if every == "true" else "some",
            _attr(elem, "name", span),
            _attr(elem, "value", span),
            span,
        )
    raise ParseError(f"unexpected <{elem.tag}>, expected <object> or <sort>", span)


def format_xml_topic(spec: TopicSpec, indent: str = "  ") -> str:
    def arg(a: TopicArg, pad: str) -> str:
        if a.kind == "object":
            value = "" if a.id_field is None else f" value={quoteattr(a.id_field)}"
            return f"{pad}<object name={quoteattr(a.name)}{value}/>"
        every = "true" if a.kind == "every" else "false"
        return (
            f'{pad}<sort all_objects="{every}" name={quoteattr(a.name)} '
            f"value={quoteattr(a.id_field or '')}/>"
        )

    quality = "".join(f" {name}={quoteattr(value)}" for name, value in format_quality(spec))
    lines = [
        f"{indent}<Topic msgtype={quoteattr(spec.msgtype)} name={quoteattr(spec.name)}{quality}>"
    ]
    if spec.entity is not None:
        lines.append(arg(spec.entity, indent * 2))
    for f in spec.features:
        if f.observations:
            lines.append(
                f"{indent * 2}<observations sensor={quoteattr(f.name)} value={quoteattr(f.field)}/>"
            )
            continue
        lines.append(f"{indent * 2}<feature name={quoteattr(f.name)} value={quoteattr(f.field)}>")
        lines += [arg(a, indent * 3) for a in f.args]
        lines.append(f"{indent * 2}</feature>")
    lines.append(f"{indent}</Topic>")
    return "\n".join(lines)


def format_xml(specs: tuple[TopicSpec, ...]) -> str:
    body = "\n".join(format_xml_topic(s) for s in specs)
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<Topic_specs>\n'
        + (body + "\n" if body else "")
        + "</Topic_specs>\n"
    )


# ---- files -------------------------------------------------------------------------------------


def read_specs(path: Path) -> SpecFile:
    return parse_specs(read_bytes(path), str(path), xml=is_xml(path))


def is_xml(path: Path) -> bool:
    """Whether a specs file is XML (else SSL_T text), by its suffix."""
    if path.suffix.lower() not in (".xml", ".sslt"):
        raise DkError(f"{path}: topic specifications must be .sslt (SSL_T text) or .xml")
    return path.suffix.lower() == ".xml"


def parse_specs(data: bytes, file: str, *, xml: bool) -> SpecFile:
    """Spec file bytes in XML or SSL_T text (UTF-8)."""
    return parse_xml(data, file) if xml else parse_text(decode(data, file), file)


def without_spans(spec: TopicSpec) -> TopicSpec:
    """`spec` with API spans, for comparing specs read from different files."""
    return replace(spec, span=Span("<api>"))
