"""The results database of `dkreason batch`: one DuckDB file, a row per (batch, run, formula).

Tables (schema version `SCHEMA`, kept in `meta`; a newer dkreason reads an older file, an older
one refuses a newer file with one line):

- `batches`: `batch_id`, `started`, `ended` (UTC), `version` (dkreason's), `config_digest`
  (the config file and the stream request it gives the formulas), `formulas` and `options`
  (JSON), so a batch is resumed only with what it started with;
- `verdicts`: `batch_id`, `run` (as given), `recording_digest` (names, sizes and modification
  times of the run's files), `formula`, `verdict` (`held`, `violated`, `undecided`, `error`),
  `t` (s from the start of the recording(s)), `time` (s on the recording's clock), `witness`,
  `instances` (JSON), `robustness`, `violations` (JSON: stream-constraint counts by kind),
  `messages` (read on the relevant topics), `seconds` (wall), `error` (one line).

Each run's rows are written in one transaction, so an interrupted batch keeps every finished
run and no half of one.
"""

from __future__ import annotations

import datetime
import json
from collections import Counter
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from .errors import DkError

SCHEMA = 1
VERDICTS = ("held", "violated", "undecided", "error")
DEFAULT_DB = Path("dkreason-results.duckdb")

_TABLES = """
CREATE TABLE IF NOT EXISTS meta (key VARCHAR PRIMARY KEY, value VARCHAR);
CREATE TABLE IF NOT EXISTS batches (
    batch_id VARCHAR PRIMARY KEY, started TIMESTAMP, ended TIMESTAMP, version VARCHAR,
    config_digest VARCHAR, formulas JSON, options JSON);
CREATE TABLE IF NOT EXISTS verdicts (
    batch_id VARCHAR, run VARCHAR, recording_digest VARCHAR, formula VARCHAR, verdict VARCHAR,
    t DOUBLE, time DOUBLE, witness VARCHAR, instances JSON, robustness DOUBLE,
    violations JSON, messages BIGINT, seconds DOUBLE, error VARCHAR);
"""


@dataclass(frozen=True, slots=True)
class Row:
    """One verdict of one formula on one run: a row of `verdicts`."""

    batch_id: str
    run: str
    recording_digest: str
    formula: str
    verdict: str
    t: float | None
    time: float | None
    witness: str | None
    instances: str | None
    robustness: float | None
    violations: str  # JSON
    messages: int
    seconds: float
    error: str | None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


COLUMNS = tuple(f.name for f in fields(Row))


@dataclass(frozen=True, slots=True)
class Change:
    """A (run, formula) whose verdict differs between two batches."""

    run: str
    formula: str
    before: str | None  # None: not in that batch
    after: str | None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


class Results:
    """A results file, opened (made when new) and checked for its schema version."""

    def __init__(self, path: Path) -> None:
        import duckdb

        self.path = path
        try:
            self.db = duckdb.connect(str(path))
        except duckdb.Error as exc:
            raise DkError(f"{path}: not a dkreason results database ({_line(exc)})") from None
        try:
            self.db.execute(_TABLES)
            found = self.db.execute("SELECT value FROM meta WHERE key = 'schema'").fetchone()
        except duckdb.Error as exc:
            self.db.close()
            raise DkError(f"{path}: not a dkreason results database ({_line(exc)})") from None
        if found is None:
            self.db.execute("INSERT INTO meta VALUES ('schema', ?)", [str(SCHEMA)])
        elif int(found[0]) > SCHEMA:
            self.db.close()
            raise DkError(
                f"{path}: written by a newer dkreason (results schema {found[0]}; this one "
                f"reads up to {SCHEMA})"
            )

    def close(self) -> None:
        self.db.close()

    def __enter__(self) -> Results:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        self.db.execute("BEGIN TRANSACTION")
        try:
            yield
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    # ---- writing a batch ----------------------------------------------------------------

    def begin(
        self,
        batch_id: str,
        version: str,
        config_digest: str,
        formulas: Sequence[str],
        options: dict[str, Any],
    ) -> None:
        self.db.execute(
            "INSERT INTO batches VALUES (?, ?, NULL, ?, ?, ?, ?)",
            [
                batch_id,
                _now(),
                version,
                config_digest,
                json.dumps(list(formulas)),
                json.dumps(options, sort_keys=True),
            ],
        )

    def resumable(
        self, config_digest: str, formulas: Sequence[str], options: dict[str, Any]
    ) -> str | None:
        """The latest batch begun with this config, these formulas and these options."""
        found = self.db.execute(
            "SELECT batch_id FROM batches WHERE config_digest = ? AND formulas = ?::JSON "
            "AND options = ?::JSON ORDER BY started DESC LIMIT 1",
            [config_digest, json.dumps(list(formulas)), json.dumps(options, sort_keys=True)],
        ).fetchone()
        return None if found is None else str(found[0])

    def done(self, batch_id: str) -> dict[str, str]:
        """Run → the recording digest its rows were made from."""
        rows = self.db.execute(
            "SELECT DISTINCT run, recording_digest FROM verdicts WHERE batch_id = ?", [batch_id]
        ).fetchall()
        return {str(run): str(digest) for run, digest in rows}

    def write(self, rows: Sequence[Row]) -> None:
        """One run's rows, in place of any earlier rows of that run in that batch."""
        with self._transaction():
            for batch_id, run in {(r.batch_id, r.run) for r in rows}:
                self.db.execute(
                    "DELETE FROM verdicts WHERE batch_id = ? AND run = ?", [batch_id, run]
                )
            self.db.executemany(
                f"INSERT INTO verdicts VALUES ({', '.join('?' * len(COLUMNS))})",
                [[getattr(r, c) for c in COLUMNS] for r in rows],
            )

    def end(self, batch_id: str) -> None:
        self.db.execute("UPDATE batches SET ended = ? WHERE batch_id = ?", [_now(), batch_id])

    # ---- reading ------------------------------------------------------------------------

    def latest(self) -> str:
        found = self.db.execute(
            "SELECT batch_id FROM batches ORDER BY started DESC LIMIT 1"
        ).fetchone()
        if found is None:
            raise DkError(f"{self.path}: no batch recorded yet")
        return str(found[0])

    def batch(self, batch_id: str | None) -> str:
        """A batch id given (or the latest), checked to exist."""
        if batch_id is None:
            return self.latest()
        if self.db.execute("SELECT 1 FROM batches WHERE batch_id = ?", [batch_id]).fetchone():
            return batch_id
        known = [
            r[0]
            for r in self.db.execute(
                "SELECT batch_id FROM batches ORDER BY started DESC LIMIT 5"
            ).fetchall()
        ]
        raise DkError(f"{self.path}: no batch {batch_id!r} (latest: {', '.join(known) or 'none'})")

    def rows(
        self, batch_id: str, formula: str | None = None, verdict: str | None = None
    ) -> list[Row]:
        if verdict is not None and verdict not in VERDICTS:
            raise DkError(f"verdict {verdict!r}: expected one of {', '.join(VERDICTS)}")
        found = self.db.execute(
            f"SELECT {', '.join(COLUMNS)} FROM verdicts WHERE batch_id = ? "
            "AND (? IS NULL OR formula = ?) AND (? IS NULL OR verdict = ?) ORDER BY run, formula",
            [batch_id, formula, formula, verdict, verdict],
        ).fetchall()
        return [Row(*r) for r in found]

    def counts(self, batch_id: str) -> dict[str, dict[str, int]]:
        """Per formula: how many runs gave each verdict."""
        out: dict[str, dict[str, int]] = {}
        for formula, verdict, n in self.db.execute(
            "SELECT formula, verdict, count(*) FROM verdicts WHERE batch_id = ? "
            "GROUP BY formula, verdict ORDER BY formula",
            [batch_id],
        ).fetchall():
            out.setdefault(str(formula), dict.fromkeys(VERDICTS, 0))[str(verdict)] = int(n)
        return out

    def violations(self, batch_id: str) -> Counter[str]:
        """Stream constraint violations per kind, over the batch's runs (each counted once,
        not once a formula)."""
        out: Counter[str] = Counter()
        for (found,) in self.db.execute(
            "SELECT any_value(violations) FROM verdicts WHERE batch_id = ? GROUP BY run",
            [batch_id],
        ).fetchall():
            out.update(json.loads(found or "{}"))
        return out

    def diff(self, before: str, after: str) -> list[Change]:
        """The (run, formula) pairs whose verdict changed from batch `before` to `after`."""
        before, after = self.batch(before), self.batch(after)
        found = self.db.execute(
            "SELECT coalesce(a.run, b.run), coalesce(a.formula, b.formula), a.verdict, "
            "b.verdict FROM (SELECT * FROM verdicts WHERE batch_id = ?) a FULL OUTER JOIN "
            "(SELECT * FROM verdicts WHERE batch_id = ?) b ON a.run = b.run AND "
            "a.formula = b.formula WHERE a.verdict IS DISTINCT FROM b.verdict ORDER BY 1, 2",
            [before, after],
        ).fetchall()
        return [Change(*r) for r in found]

    def to_parquet(self, batch_id: str, out: Path) -> None:
        self.db.execute(
            f"COPY (SELECT * FROM verdicts WHERE batch_id = '{_quoted(batch_id)}' "
            f"ORDER BY run, formula) TO '{_quoted(str(out))}' (FORMAT parquet)"
        )


def _quoted(text: str) -> str:
    return text.replace("'", "''")


def _now() -> datetime.datetime:
    return datetime.datetime.now(datetime.UTC).replace(tzinfo=None)


def _line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
