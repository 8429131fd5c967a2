"""Editing a specs file through its parsed model, so no edit can lose a topic.

Under a lock beside the file, the current file is read and parsed; only the changed topic's
source extent is cut out or a new topic is put at the model's `tail`, in the file's own line
ends and indentation; the result is parsed again and must equal the intended model before it
replaces the file.  Any layout — one line, topics sharing lines, any line terminator, XML of
any shape — is therefore either edited exactly or refused with the file left as it was.
"""

from __future__ import annotations

import re
from pathlib import Path

from ..errors import DkError, NameError_, ParseError, Span
from ..inputs import files
from ..model import TopicSpec
from . import sslt


def edit(path: Path, *, add: TopicSpec | None = None, remove: str | None = None) -> None:
    """Remove topic `remove` and/or append `add` to the specs file at `path` (created when
    missing)."""
    with files.locked(path) as target:
        xml = target.suffix.lower() == ".xml"
        data = (
            files.read_bytes(target)
            if target.exists()
            else (sslt.format_xml(()).encode() if xml else b"")
        )
        where = files.shown(path)
        current = sslt.parse_specs(data, where, xml=xml)
        names = [s.name for s in current.specs]
        intended = [s for s in current.specs if s.name != remove]
        if remove is not None and remove not in names:
            raise NameError_(
                f"no topic {remove!r} to remove (topics: {', '.join(names) or 'none'})", Span(where)
            )
        if add is not None:
            if add.name in names and add.name != remove:
                raise NameError_(
                    f"topic {add.name} is already specified (line "
                    f"{current.specs[names.index(add.name)].span.line})",
                    Span(where),
                )
            intended.append(add)
        new = _apply(data, current, xml, names.index(remove) if remove is not None else None, add)
        if list(sslt.parse_specs(new, where, xml=xml).specs) != intended:
            raise ParseError(
                "this edit would change other topics of the file (an unusual "
                "layout); the file is left unchanged",
                Span(where),
            )
        files.write_atomic(target, new)


def _apply(
    data: bytes, current: sslt.SpecFile, xml: bool, index: int | None, add: TopicSpec | None
) -> bytes:
    """The edited file; XML extents count bytes, text extents characters."""
    encoding = _encoding(data) if xml else "utf-8"
    try:
        text = data.decode(encoding)
    except (LookupError, UnicodeDecodeError):
        raise DkError(f"cannot edit a specs file in encoding {encoding!r}; use UTF-8") from None

    def char(offset: int) -> int:
        return len(data[:offset].decode(encoding)) if xml else offset

    newline, tail = _newline(text), char(current.tail)
    if index is not None:
        start, end = _whole_lines(text, *(char(x) for x in current.extents[index]))
        text = text[:start] + text[end:]
        tail -= end - start if tail >= end else 0
    if add is not None:
        text = _insert_xml(text, tail, add, newline) if xml else _append_text(text, add, newline)
    return text.encode(encoding, errors="xmlcharrefreplace" if xml else "strict")


def _encoding(data: bytes) -> str:
    declared = re.match(rb"<\?xml[^>]*encoding\s*=\s*[\"']([A-Za-z0-9._-]+)[\"']", data)
    return declared.group(1).decode() if declared else "utf-8"


def _newline(text: str) -> str:
    found = re.search(r"\r\n|\n|\r", text)
    return found.group(0) if found else "\n"


def _line_start(text: str, at: int) -> int:
    return max(text.rfind("\n", 0, at), text.rfind("\r", 0, at)) + 1


def _line_end(text: str, at: int) -> int:
    """Just past the line terminator of the line holding `at` (or the end of the text)."""
    ends = [i for i in (text.find("\n", at), text.find("\r", at)) if i >= 0]
    if not ends:
        return len(text)
    i = min(ends)
    return i + 2 if text.startswith("\r\n", i) else i + 1


def _whole_lines(text: str, start: int, end: int) -> tuple[int, int]:
    """The extent to cut for a topic at [start, end): its whole lines when it has them to
    itself (a trailing comment goes with it), else just the topic and the blanks after it."""
    first, last = _line_start(text, start), _line_end(text, end)
    after = text[end:last].strip()
    if not text[first:start].strip() and (not after or after.startswith("#")):
        return first, last
    while end < len(text) and text[end] in " \t":
        end += 1
    return start, end


def _append_text(text: str, add: TopicSpec, newline: str) -> str:
    if text and not text.endswith(("\n", "\r")):
        text += newline
    return text + sslt.format_spec(add) + newline


def _insert_xml(text: str, tail: int, add: TopicSpec, newline: str) -> str:
    """`add` before `</Topic_specs>` at `tail`, indented like the file's topics."""
    indent = re.search(r"^([ \t]*)<Topic\b", text, re.M)
    pad = indent.group(1) if indent and indent.group(1) else "  "
    topic = sslt.format_xml_topic(add, pad).replace("\n", newline)
    if text.startswith("</", tail):
        first = _line_start(text, tail)
        if not text[first:tail].strip():
            return text[:first] + topic + newline + text[first:]
        return text[:tail] + newline + topic + newline + text[tail:]
    # an empty root element, `<Topic_specs/>`: open it
    open_at = text.rfind("<Topic_specs", 0, tail)
    if open_at < 0:
        raise DkError("cannot add a topic: no <Topic_specs> element")
    head = text[open_at:tail].rstrip()[:-2].rstrip()
    return text[:open_at] + head + ">" + newline + topic + newline + "</Topic_specs>" + text[tail:]
