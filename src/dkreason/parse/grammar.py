"""lark's LALR parsers, their tables kept as dkreason cache entries.

Analysing a grammar costs 30-40 ms.  lark's own cache would save that, but it unpickles a file
of a fixed name before it checks anything and writes through whatever that name is; the tables
are an ordinary entry of dkreason's cache instead, keyed by the grammar and lark's version and
signed and verified like every entry (dkreason.cache).
"""

from __future__ import annotations

import io
from importlib import resources
from typing import Any

import lark
from lark import Lark, Transformer

from .. import cache


def lalr(grammar: str, transformer: Transformer[Any, Any]) -> Lark:
    """The LALR parser of `grammar` (a file of this package) that runs `transformer` as it
    parses, so no parse tree is built."""
    text = resources.files(__package__).joinpath(grammar).read_text(encoding="utf-8")

    def tables() -> bytes:
        parser = Lark(text, parser="lalr", maybe_placeholders=False, transformer=transformer)
        out = io.BytesIO()
        parser.save(out)
        return out.getvalue()

    saved = cache.cached("lark", [grammar, text, lark.__version__], tables)
    return Lark.load(io.BytesIO(saved))
