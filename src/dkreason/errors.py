"""Errors a user's input can cause, each rendered as one line naming where it happened.

DkError                    anything the CLI prints as one line and exits 2 on
├── WireError              a peer on the network sent something malformed (dkreason.live)
└── SourceError            carries a Span (file, line, column) of the offending text
    ├── ParseError         grammar or well-formedness failures (SSL_T, formulas, XML, RDF, TOML)
    ├── NameError_         unknown or ambiguous names (feature, sort, object, topic, platform)
    ├── SortError          wrong arity or an argument of the wrong sort
    ├── MissingIdError     an object without id where a topic filter needs one
    └── RuleError          a rule file (or a query) the checker refuses
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Span:
    """Where a piece of input came from; zero line/column means "the whole file"."""

    file: str
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        if self.line and self.column:
            return f"{self.file}:{self.line}:{self.column}"
        if self.line:
            return f"{self.file}:{self.line}"
        return self.file


def one_line(text: str) -> str:
    """`text` with line breaks and other control characters escaped: an error is one line."""
    return (
        text
        if text.isprintable()
        else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    )


class DkError(Exception):
    """Base of every error caused by input; `str()` is the one line shown to the user."""


class WireError(DkError):
    """A peer sent something malformed: logged and dropped, never fatal.  `kind` (size, json,
    token, cdr, signature, …) groups what is logged once per peer."""

    def __init__(self, message: str, kind: str = "knowledge") -> None:
        super().__init__(message)
        self.kind = kind


class SourceError(DkError):
    def __init__(self, message: str, span: Span) -> None:
        super().__init__(f"{span}: {message}")
        self.message, self.span = message, span


class ParseError(SourceError):
    pass


class NameError_(SourceError):
    pass


class SortError(SourceError):
    pass


class MissingIdError(SourceError):
    pass


class RuleError(SourceError):
    pass
