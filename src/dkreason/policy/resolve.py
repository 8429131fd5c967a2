"""Constants of rule files as written: a quoted local name (`'Altitude'`), a prefixed one
(`'hr:Heading'`, with a prefix an ontology declares) or a full IRI (`'<http://…#UAV>'`, or
unbracketed) stands for the entity's IRI, as it would in a formula; resolved once, at load.

A name two platforms give to different IRIs is an error naming both, as in formulas.  A string
no ontology names is kept as written: platform and topic names, fields, kinds, ''.  The checker
warns about one that no fact holds (a misspelt name)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from ..errors import NameError_, Span
from ..names import NameIndex
from .syntax import Comparison, Condition, Fact, Literal, Rule, RuleFile, Term


class Names:
    """The names of every platform at hand."""

    def __init__(self, indexes: Sequence[NameIndex]) -> None:
        self.indexes = indexes
        self._seen: dict[str, str] = {}

    def iri(self, written: str, span: Span) -> str:
        """The IRI `written` names, or `written` itself if it names none."""
        if written in self._seen:
            return self._seen[written]
        if written.startswith("<") and written.endswith(">"):
            return written[1:-1]
        found = {iri: index.platform for index in self.indexes for iri in index.lookup(written)}
        if len(found) > 1:
            both = " and ".join(f"<{iri}> ({found[iri]})" for iri in sorted(found))
            raise NameError_(
                f"ambiguous name {written!r}: {both}; write a prefixed name or a full <IRI>", span
            )
        self._seen[written] = next(iter(found), written)
        return self._seen[written]


def resolve(f: RuleFile, names: Names) -> RuleFile:
    """The file with every string constant of its rules and facts as the IRI it names (what
    names nothing stays as it is, the same objects)."""

    def term(t: Term, span: Span) -> Term:
        return names.iri(t, span) if isinstance(t, str) and t else t

    def terms(args: tuple[Term, ...], spans: tuple[Span, ...], at: Span) -> tuple[Term, ...]:
        new = tuple(term(a, s) for a, s in zip(args, spans or (at,) * len(args), strict=True))
        return args if new == args else new

    def condition(c: Condition) -> Condition:
        if isinstance(c, Comparison):
            left, right = terms((c.left, c.right), c.spans, c.span)
            return c if (left, right) == (c.left, c.right) else replace(c, left=left, right=right)
        return literal(c)

    def literal(lit: Literal) -> Literal:
        args = terms(lit.args, lit.spans, lit.span)
        return lit if args is lit.args else replace(lit, args=args)

    def rule(r: Rule) -> Rule:
        head, body = literal(r.head), tuple(condition(c) for c in r.body)
        same = head is r.head and all(a is b for a, b in zip(body, r.body, strict=True))
        return r if same else replace(r, head=head, body=body)

    def fact(x: Fact) -> Fact:
        row = terms(x.row, (), x.span)
        return x if row is x.row else replace(x, row=row)  # type: ignore[arg-type]

    return replace(f, rules=tuple(map(rule, f.rules)), facts=tuple(map(fact, f.facts)))
