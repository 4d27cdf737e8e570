"""The console's database as a version store: the measurements and model versions the browser
shows, read and written by the command line (``tracker model fit|history --db PATH``).

This module owns the two tables (the console's ``app/db.py`` creates them from :data:`TABLES`)
and the JSON of a stored model and fit, so a version made in the browser and one made on the
command line are the same record. A log is found in the database by its data (same samples and
values), not its file name: the CSV the console stored and the file on disk may differ in
formatting. Every write is one ``BEGIN IMMEDIATE`` transaction (with a busy timeout: the console
may be writing at the same moment); the file must already be a console database — nothing here
creates or migrates one.
"""

from __future__ import annotations

import json
import math
import sqlite3
import time
from collections.abc import Iterator, Mapping
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tracker.errors import ConfigError, DataError
from tracker.plant.model import AxisModel
from tracker.workbench.budget import ErrorBudget
from tracker.workbench.measurements.data import Measurement, parse_log
from tracker.workbench.versions import ModelVersion, VersionHistory

TABLES = """
CREATE TABLE IF NOT EXISTS measurements (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL,
    axis TEXT NOT NULL,
    csv TEXT NOT NULL,
    n INTEGER NOT NULL,
    dt_s REAL NOT NULL,
    created_s REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS model_versions (
    id INTEGER PRIMARY KEY,
    measurement_id INTEGER NOT NULL REFERENCES measurements(id) ON DELETE CASCADE,
    parent_id INTEGER,
    label TEXT NOT NULL,
    model TEXT NOT NULL,
    fit TEXT NOT NULL,
    created_s REAL NOT NULL
);
"""


def model_record(model: AxisModel, axis: str) -> dict[str, Any]:
    """A model as a version stores it (the console's JSON)."""
    return {
        "axis": axis,
        "gain_nm_per_v": model.gain_nm_per_v,
        "effects": list(model.effects),
        "params": {k: float(v) for k, v in model.params.items()},
    }


def model_from_record(data: Mapping[str, Any]) -> AxisModel:
    """A stored model back (parameters as stored, not reset to defaults)."""
    params = {str(k): float(v) for k, v in data["params"].items()}
    return AxisModel.create(float(data["gain_nm_per_v"]), params, tuple(data["effects"]), params)


def _finite(v: Any) -> Any:  # noqa: ANN401 - any JSON value
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {str(k): _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    if isinstance(v, np.generic):
        return _finite(v.item())
    return v


def fit_record(version: ModelVersion, extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A version's figures as the console stores them (``extra``: the fitter's own output)."""
    out: dict[str, Any] = {
        "fit_percent": version.fit_percent,
        "fit_percent_increment": version.fit_percent_increment,
        "rms_deg": version.rms_deg,
        "horizon_s": version.horizon_s,
        "stderr": dict(version.stderr),
        "params": {k: float(v) for k, v in version.model.params.items()},
    }
    out.update(extra or {})
    if version.budget is not None:
        out["budget"] = version.budget.to_dict()
    return _finite(out)  # type: ignore[no-any-return]


def version_from_row(number: int, row: Mapping[str, Any], source: str) -> ModelVersion:
    """A stored row (``model`` and ``fit`` decoded) as the ``number``-th version."""
    fit = row["fit"]
    b = fit.get("budget")

    def num(key: str) -> float:
        v = fit.get(key)
        return math.nan if v is None else float(v)

    return ModelVersion(
        number=number,
        model=model_from_record(row["model"]),
        change=str(row["label"]),
        fit_percent=num("fit_percent"),
        fit_percent_increment=num("fit_percent_increment"),
        rms_deg=num("rms_deg"),
        stderr={str(k): float(v) for k, v in (fit.get("stderr") or {}).items() if v is not None},
        data_source=source,
        horizon_s=num("horizon_s"),
        created_utc=time.strftime("%Y-%m-%dT%H:%M:%S+00:00", time.gmtime(float(row["created_s"]))),
        budget=ErrorBudget.from_dict(b) if isinstance(b, Mapping) else None,
    )


@dataclass(frozen=True, slots=True)
class StoredMeasurement:
    """A measurement of the console's database (``id`` as the console shows it: #id)."""

    id: int
    name: str
    axis: str


@contextmanager
def immediate_transaction(conn: sqlite3.Connection) -> Iterator[sqlite3.Connection]:
    """One write transaction on ``conn`` (autocommit mode): BEGIN IMMEDIATE, COMMIT when the
    block ends, ROLLBACK if it raises. The console's database (app/db.py) uses it too."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        yield conn
    except BaseException:
        conn.execute("ROLLBACK")
        raise
    conn.execute("COMMIT")


class ConsoleDatabase:
    """The console's SQLite file, opened for its measurements and model versions."""

    def __init__(self, path: str | Path, timeout_s: float = 10.0) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise ConfigError(
                f"--db {self.path}: no such file; give the console's database "
                "(data_dir/console.sqlite3, e.g. data/console.sqlite3)"
            )
        try:
            self._conn = sqlite3.connect(str(self.path), timeout=timeout_s, isolation_level=None)
            self._conn.row_factory = sqlite3.Row
            self._conn.execute("PRAGMA foreign_keys = ON")
            names = {r[0] for r in self._conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.DatabaseError as exc:
            raise ConfigError(f"--db {self.path}: not an SQLite database ({exc})") from None
        missing = {"measurements", "model_versions"} - names
        if missing:
            self._conn.close()
            raise ConfigError(
                f"--db {self.path}: not the console's database (no table {', '.join(sorted(missing))})"
            )

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> ConsoleDatabase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _tx(self) -> AbstractContextManager[sqlite3.Connection]:
        return immediate_transaction(self._conn)

    def measurements(self) -> list[StoredMeasurement]:
        rows = self._conn.execute("SELECT id, name, axis FROM measurements ORDER BY id").fetchall()
        return [StoredMeasurement(int(r["id"]), r["name"], r["axis"]) for r in rows]

    def measurement_text(self, mid: int) -> str:
        """A stored log's CSV text; ConfigError when there is no such measurement."""
        row = self._conn.execute("SELECT csv FROM measurements WHERE id = ?", (mid,)).fetchone()
        if row is None:
            raise ConfigError(f"--db {self.path}: no measurement #{mid}")
        return str(row["csv"])

    def _find(self, conn: sqlite3.Connection, meas: Measurement) -> StoredMeasurement | None:
        rows = conn.execute(
            "SELECT id, name, axis, csv FROM measurements WHERE n = ? ORDER BY id DESC", (meas.n,)
        ).fetchall()
        for r in rows:
            try:
                other = parse_log(r["csv"], r["name"])
            except (DataError, ValueError):
                continue
            if _same_data(meas, other):
                return StoredMeasurement(int(r["id"]), r["name"], r["axis"])
        return None

    def find(self, meas: Measurement) -> StoredMeasurement | None:
        """The newest stored measurement with the same data as ``meas``, or None."""
        return self._find(self._conn, meas)

    def history(self, mid: int) -> tuple[VersionHistory, list[int]]:
        """The versions of measurement ``mid``, oldest first, and their row ids."""
        rows = self._conn.execute(
            "SELECT * FROM model_versions WHERE measurement_id = ? ORDER BY id", (mid,)
        ).fetchall()
        out = []
        for i, r in enumerate(rows, start=1):
            rec = {**dict(r), "model": json.loads(r["model"]), "fit": json.loads(r["fit"])}
            try:
                out.append(version_from_row(i, rec, f"measurement #{mid}"))
            except (KeyError, TypeError, ValueError, AssertionError) as exc:
                raise DataError(
                    f"--db {self.path}: version id {r['id']}: not a model version ({exc})"
                ) from None
        return VersionHistory(tuple(out)), [int(r["id"]) for r in rows]

    def append(
        self,
        meas: Measurement,
        text: str,
        name: str,
        axis: str,
        version: ModelVersion,
        extra: Mapping[str, Any] | None = None,
    ) -> tuple[StoredMeasurement, int]:
        """Store ``version`` as the newest version of the measurement with ``meas``'s data (stored
        first, as ``name`` with the CSV ``text``, when the database does not have it yet); one
        transaction. Returns the measurement and the new version's row id."""
        model_json = json.dumps(model_record(version.model, axis))
        fit_json = json.dumps(fit_record(version, extra))
        with self._tx() as c:
            found = self._find(c, meas)
            if found is None:
                cur = c.execute(
                    "INSERT INTO measurements (name, axis, csv, n, dt_s, created_s) "
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    (name, axis, text, meas.n, meas.dt_s, time.time()),
                )
                found = StoredMeasurement(int(cur.lastrowid or 0), name, axis)
            last = c.execute(
                "SELECT MAX(id) FROM model_versions WHERE measurement_id = ?", (found.id,)
            ).fetchone()[0]
            cur = c.execute(
                "INSERT INTO model_versions (measurement_id, parent_id, label, model, fit, created_s) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (found.id, last, version.change, model_json, fit_json, time.time()),
            )
            return found, int(cur.lastrowid or 0)


def _same_data(a: Measurement, b: Measurement) -> bool:
    if a.n != b.n:
        return False
    scale = float(np.max(np.abs(a.theta_rad))) or 1.0
    return bool(
        np.allclose(a.t_s, b.t_s, rtol=0, atol=1e-9 + 1e-9 * abs(float(a.t_s[-1])))
        and np.allclose(a.u_v, b.u_v, rtol=1e-9, atol=1e-9)
        and np.allclose(a.theta_rad, b.theta_rad, rtol=0, atol=1e-9 * scale + 1e-12)
    )


__all__ = [
    "TABLES",
    "immediate_transaction",
    "ConsoleDatabase",
    "StoredMeasurement",
    "fit_record",
    "model_from_record",
    "model_record",
    "version_from_row",
]
