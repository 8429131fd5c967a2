"""State files: JSON lines `{"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5}}`.

Numbers are read as decimals, so times compare exactly (0.1 is one tenth, as written)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path
from typing import Any

from ..errors import ParseError, Span


def read_states(path: Path) -> Iterator[tuple[Any, dict[str, Any]]]:
    try:
        handle = path.open(encoding="utf-8")
    except OSError as exc:
        raise ParseError(f"cannot read states ({exc.strerror})", Span(str(path))) from None
    with handle:
        for n, line in enumerate(handle, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line, parse_float=Decimal)
            except json.JSONDecodeError as exc:
                raise ParseError(f"not JSON: {exc.msg}", Span(str(path), n, exc.colno)) \
                    from None
            if not isinstance(row, dict) or "time" not in row or \
                    not isinstance(row.get("values"), dict):
                raise ParseError('expected {"time": …, "values": {…}}', Span(str(path), n))
            yield row["time"], {k: float(v) if isinstance(v, Decimal) else v
                                for k, v in row["values"].items()}
