"""State files: JSON lines `{"time": 0.0, "values": {"P[a]": true, "X[a]": 3.5, "M[a]": "AUTO"}}`.

Numbers are read as decimals, so times compare exactly (0.1 is one tenth, as written)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from decimal import Decimal
from pathlib import Path
from typing import Any

from ..errors import DkError, ParseError, Span
from ..inputs import files
from ..inputs.numbers import datum
from ..model import FeatureKey
from ..parse.formula import feature_key
from .progressor import exact_time
from .state import USE


def read_states(
    path: Path, uses: Mapping[FeatureKey, str] | None = None
) -> Iterator[tuple[Any, dict[FeatureKey, Any]]]:
    """(time, values) per line; a value is a boolean, a number, a string or null (unknown);
    NaN and infinities are unknown too.  `uses`: how the formulas use each feature (bool,
    number, string); a value of another kind is an error naming the file and line."""
    for n, line in files.lines(path, str(path)):
        if not line.strip():
            continue
        where = Span(str(path), n)
        row = files.json_value(line, where)
        if (
            not isinstance(row, dict)
            or "time" not in row
            or not isinstance(row.get("values"), dict)
        ):
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
            elif value is not None and not isinstance(value, bool | int | float | str):
                raise ParseError(
                    f"value of {text} must be a boolean, a number, a string or "
                    f"null, not {type(value).__name__}",
                    where,
                )
            values[key] = datum(value)
            use = (uses or {}).get(key)
            if use is not None and value is not None:
                kind = (
                    "bool"
                    if isinstance(value, bool)
                    else "string"
                    if isinstance(value, str)
                    else "number"
                )
                if kind != use:
                    raise ParseError(
                        f"{text} is {USE[kind]} ({value!r}), but a formula uses it as {USE[use]}",
                        where,
                    )
        yield row["time"], values
