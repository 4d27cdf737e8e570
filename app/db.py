"""SQLite storage for the service: API keys (hashes only), presets, measurements, model versions, jobs.

Every write is one transaction (``with self._conn``): it lands whole or not at all, so bad input
that is refused half-way leaves the stored data as it was. Callers validate before writing.
The connection is shared between the event loop and worker threads behind one lock.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tracker.workbench.version_db import TABLES as VERSION_TABLES
from tracker.workbench.version_db import immediate_transaction

SCHEMA = (
    """
CREATE TABLE IF NOT EXISTS api_keys (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL,
    role TEXT NOT NULL,
    key_hash TEXT NOT NULL UNIQUE,
    prefix TEXT NOT NULL,
    created_s REAL NOT NULL,
    revoked INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS presets (
    name TEXT PRIMARY KEY,
    pan_deg REAL NOT NULL,
    tilt_deg REAL NOT NULL,
    created_s REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS jobs (
    id INTEGER PRIMARY KEY,
    kind TEXT NOT NULL,
    params TEXT NOT NULL,
    state TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    message TEXT NOT NULL DEFAULT '',
    result TEXT,
    created_s REAL NOT NULL,
    finished_s REAL
);
CREATE TABLE IF NOT EXISTS kv (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
"""
    + VERSION_TABLES  # measurements and model_versions: shared with `tracker model --db`
)


@dataclass(frozen=True, slots=True)
class KeyRecord:
    """A stored API key (the key itself is never stored, only its hash)."""

    id: int
    name: str
    role: str
    prefix: str
    created_s: float
    revoked: bool


class Database:
    """The service's SQLite file. Thread-safe; every method is one transaction."""

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        if str(path) != ":memory:":
            self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
            self.path.touch(mode=0o600, exist_ok=True)  # key hashes live here: owner only
        self._lock = threading.RLock()
        self._conn = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._conn.row_factory = sqlite3.Row
        self._conn.execute("PRAGMA foreign_keys = ON")
        if str(path) != ":memory:":
            self._conn.execute("PRAGMA journal_mode = WAL")
        self._conn.executescript(SCHEMA)

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    @contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        with self._lock, immediate_transaction(self._conn) as conn:
            yield conn

    def transaction(self) -> AbstractContextManager[sqlite3.Connection]:
        """One write transaction for the modules that keep their own tables (app/persist.py,
        app/audit.py): it commits whole when the block ends, rolls back if it raises."""
        return self._tx()

    def ensure_tables(self, schema: str) -> None:
        """Run ``CREATE TABLE IF NOT EXISTS ...`` statements of a module that keeps its own tables."""
        with self._lock:
            self._conn.executescript(schema)

    def rows(self, sql: str, args: tuple[Any, ...] = ()) -> list[sqlite3.Row]:
        """The rows of a read-only query."""
        return self._all(sql, args)

    def _all(self, sql: str, args: tuple[Any, ...] = ()) -> list[sqlite3.Row]:
        with self._lock:
            return list(self._conn.execute(sql, args).fetchall())

    def _one(self, sql: str, args: tuple[Any, ...] = ()) -> sqlite3.Row | None:
        with self._lock:
            row: sqlite3.Row | None = self._conn.execute(sql, args).fetchone()
            return row

    # --- keys -----------------------------------------------------------------------------------
    def add_key(self, name: str, role: str, key_hash: str, prefix: str) -> int:
        with self._tx() as c:
            cur = c.execute(
                "INSERT INTO api_keys (name, role, key_hash, prefix, created_s) VALUES (?, ?, ?, ?, ?)",
                (name, role, key_hash, prefix, time.time()),
            )
            return int(cur.lastrowid or 0)

    def key_by_hash(self, key_hash: str) -> KeyRecord | None:
        row = self._one("SELECT * FROM api_keys WHERE key_hash = ?", (key_hash,))
        return _key(row) if row else None

    def list_keys(self) -> list[KeyRecord]:
        return [_key(r) for r in self._all("SELECT * FROM api_keys ORDER BY id")]

    def revoke_key(self, key_id: int) -> bool:
        with self._tx() as c:
            return c.execute("UPDATE api_keys SET revoked = 1 WHERE id = ?", (key_id,)).rowcount > 0

    def count_keys(self) -> int:
        row = self._one("SELECT COUNT(*) AS n FROM api_keys")
        return int(row["n"]) if row else 0

    # --- presets --------------------------------------------------------------------------------
    def put_preset(self, name: str, pan_deg: float, tilt_deg: float) -> None:
        with self._tx() as c:
            c.execute(
                "INSERT INTO presets (name, pan_deg, tilt_deg, created_s) VALUES (?, ?, ?, ?) "
                "ON CONFLICT(name) DO UPDATE SET pan_deg = excluded.pan_deg, tilt_deg = excluded.tilt_deg",
                (name, pan_deg, tilt_deg, time.time()),
            )

    def get_preset(self, name: str) -> dict[str, Any] | None:
        row = self._one("SELECT name, pan_deg, tilt_deg FROM presets WHERE name = ?", (name,))
        return dict(row) if row else None

    def list_presets(self) -> list[dict[str, Any]]:
        return [dict(r) for r in self._all("SELECT name, pan_deg, tilt_deg FROM presets ORDER BY name")]

    def delete_preset(self, name: str) -> bool:
        with self._tx() as c:
            return c.execute("DELETE FROM presets WHERE name = ?", (name,)).rowcount > 0

    # --- measurements ---------------------------------------------------------------------------
    def add_measurement(self, name: str, axis: str, csv_text: str, n: int, dt_s: float) -> int:
        with self._tx() as c:
            cur = c.execute(
                "INSERT INTO measurements (name, axis, csv, n, dt_s, created_s) VALUES (?, ?, ?, ?, ?, ?)",
                (name, axis, csv_text, n, dt_s, time.time()),
            )
            return int(cur.lastrowid or 0)

    def list_measurements(self) -> list[dict[str, Any]]:
        return [
            dict(r)
            for r in self._all(
                "SELECT id, name, axis, n, dt_s, created_s, CASE WHEN instr(substr(csv, 1, "
                "instr(csv || char(10), char(10))), 'speed_cmd') > 0 THEN 'camera' ELSE 'dc' END AS kind "
                "FROM measurements ORDER BY id"  # kind: a camera log's header has speed_cmd
            )
        ]

    def get_measurement(self, mid: int) -> dict[str, Any] | None:
        row = self._one("SELECT * FROM measurements WHERE id = ?", (mid,))
        return dict(row) if row else None

    def get_measurement_meta(self, mid: int) -> dict[str, Any] | None:
        """A measurement's record without its CSV text."""
        row = self._one("SELECT id, name, axis, n, dt_s, created_s FROM measurements WHERE id = ?", (mid,))
        return dict(row) if row else None

    def delete_measurement(self, mid: int) -> bool:
        with self._tx() as c:
            return c.execute("DELETE FROM measurements WHERE id = ?", (mid,)).rowcount > 0

    # --- model versions -------------------------------------------------------------------------
    def add_version(
        self,
        measurement_id: int,
        parent_id: int | None,
        label: str,
        model: dict[str, Any],
        fit: dict[str, Any],
    ) -> int:
        with self._tx() as c:
            cur = c.execute(
                "INSERT INTO model_versions (measurement_id, parent_id, label, model, fit, created_s) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (measurement_id, parent_id, label, json.dumps(model), json.dumps(fit), time.time()),
            )
            return int(cur.lastrowid or 0)

    def list_versions(self, measurement_id: int) -> list[dict[str, Any]]:
        rows = self._all(
            "SELECT * FROM model_versions WHERE measurement_id = ? ORDER BY id", (measurement_id,)
        )
        return [_version(r) for r in rows]

    def get_version(self, vid: int) -> dict[str, Any] | None:
        row = self._one("SELECT * FROM model_versions WHERE id = ?", (vid,))
        return _version(row) if row else None

    # --- jobs -----------------------------------------------------------------------------------
    def add_job(self, kind: str, params: dict[str, Any]) -> int:
        with self._tx() as c:
            cur = c.execute(
                "INSERT INTO jobs (kind, params, state, created_s) VALUES (?, ?, 'queued', ?)",
                (kind, json.dumps(params), time.time()),
            )
            return int(cur.lastrowid or 0)

    def update_job(
        self,
        job_id: int,
        *,
        state: str | None = None,
        progress: float | None = None,
        message: str | None = None,
        result: dict[str, Any] | None = None,
    ) -> None:
        sets: list[str] = []
        args: list[Any] = []
        for col, val in (("state", state), ("progress", progress), ("message", message)):
            if val is not None:
                sets.append(f"{col} = ?")
                args.append(val)
        if result is not None:
            sets.append("result = ?")
            args.append(json.dumps(result))
        if state in {"done", "failed", "cancelled"}:
            sets.append("finished_s = ?")
            args.append(time.time())
        if not sets:
            return
        with self._tx() as c:
            c.execute(f"UPDATE jobs SET {', '.join(sets)} WHERE id = ?", (*args, job_id))

    def get_job(self, job_id: int) -> dict[str, Any] | None:
        row = self._one("SELECT * FROM jobs WHERE id = ?", (job_id,))
        return _job(row) if row else None

    def list_jobs(self, limit: int = 50) -> list[dict[str, Any]]:
        rows = self._all("SELECT * FROM jobs ORDER BY id DESC LIMIT ?", (limit,))
        return [_job(r, with_result=False) for r in rows]

    def fail_unfinished_jobs(self) -> None:
        """At start-up: jobs left running by a previous process will never finish."""
        with self._tx() as c:
            c.execute(
                "UPDATE jobs SET state = 'failed', message = 'service restarted', finished_s = ? "
                "WHERE state IN ('queued', 'running')",
                (time.time(),),
            )

    # --- small key/value store (practice rig secret, camera policy) ---------------------------
    def put_value(self, key: str, value: dict[str, Any]) -> None:
        with self._tx() as c:
            c.execute(
                "INSERT INTO kv (key, value) VALUES (?, ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                (key, json.dumps(value)),
            )

    def get_value(self, key: str) -> dict[str, Any] | None:
        row = self._one("SELECT value FROM kv WHERE key = ?", (key,))
        return json.loads(row["value"]) if row else None

    def delete_value(self, key: str) -> None:
        with self._tx() as c:
            c.execute("DELETE FROM kv WHERE key = ?", (key,))


def _key(row: sqlite3.Row) -> KeyRecord:
    return KeyRecord(
        int(row["id"]), row["name"], row["role"], row["prefix"], float(row["created_s"]), bool(row["revoked"])
    )


def _version(row: sqlite3.Row) -> dict[str, Any]:
    return {
        "id": int(row["id"]),
        "measurement_id": int(row["measurement_id"]),
        "parent_id": row["parent_id"],
        "label": row["label"],
        "model": json.loads(row["model"]),
        "fit": json.loads(row["fit"]),
        "created_s": float(row["created_s"]),
    }


def _job(row: sqlite3.Row, with_result: bool = True) -> dict[str, Any]:
    out = {
        "id": int(row["id"]),
        "kind": row["kind"],
        "params": json.loads(row["params"]),
        "state": row["state"],
        "progress": float(row["progress"]),
        "message": row["message"],
        "created_s": float(row["created_s"]),
        "finished_s": row["finished_s"],
    }
    if with_result:
        out["result"] = json.loads(row["result"]) if row["result"] else None
    return out
