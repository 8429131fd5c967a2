"""State files: JSON lines `{"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5}}`.

Numbers are read as decimals, so times compare exactly (0.1 is one tenth, as written)."""

from __future__ import annotations

from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span
from ..model import FeatureKey
from ..numbers import datum
from ..parse import files
from ..parse.formula import feature_key
from .progressor import exact_time


def read_states(path: Path) -> Iterator[tuple[Any, dict[FeatureKey, Any]]]:
    """(time, values) per line; a value is a boolean, a number or null (unknown); NaN and
    infinities are unknown too."""
    for n, line in files.lines(path, str(path)):
        if not line.strip():
            continue
        where = Span(str(path), n)
        row = files.json_value(line, where)
        if not isinstance(row, dict) or "time" not in row or \
                not isinstance(row.get("values"), dict):
            raise ParseError('expected {"time": …, "values": {…}}', where)
        try:
            exact_time(row["time"])  # finite and bounded, before the progressor converts it
        except DkError as exc:
            raise ParseError(str(exc), where) from None
        values = {}
        for text, value in row["values"].items():
            key = feature_key(text)
            if key is None:
                raise ParseError(f"{text!r} is not a feature (Name or Name[arg, …])", where)
            if isinstance(value, Decimal):
                value = float(value)
            elif value is not None and not isinstance(value, bool | int | float):
                raise ParseError(f"value of {text} must be a boolean, a number or null, not "
                                 f"{type(value).__name__}", where)
            values[key] = datum(value)
        yield row["time"], values
