"""Settings that survive a restart: a ``settings`` table of key → JSON value, each with a version.

Any part of the service that holds a setting in memory keeps it here too and reads it back at
start-up. A key names one setting (``"console.gains.pan"``, ``"audio.policy"``); its value is any
JSON (finite numbers only); its ``version`` is the shape of that value, so a reader that finds an
older shape can convert it or fall back to its default instead of misreading it.

:meth:`SettingsStore.write` changes several keys in one SQLite transaction: a crash mid-write
(``kill -9``, power loss) leaves either all of them changed or none. Validation is the reader's
job: a value may have been stored by an older version of the service whose checks were
looser, so read it back through the same checks as a new value and fall back when they refuse.

    store = SettingsStore(db)
    store.write({"audio.policy": {"hold_s": 2.0}}, version=1)
    got = store.get("audio.policy")          # Stored(key, version, value, updated_s) or None
    store.write({}, deletes=["audio.policy"])  # back to the default
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from app.db import Database
from tracker.errors import DataError

SCHEMA = """
CREATE TABLE IF NOT EXISTS settings (
    key TEXT PRIMARY KEY,
    version INTEGER NOT NULL,
    value TEXT NOT NULL,
    updated_s REAL NOT NULL
);
"""


@dataclass(frozen=True, slots=True)
class Stored:
    """One stored setting: its key, the version of its value's shape, the value, when written."""

    key: str
    version: int
    value: Any
    updated_s: float


class SettingsStore:
    """The ``settings`` table of the service's database (see the module docstring)."""

    def __init__(self, db: Database) -> None:
        self.db = db
        db.ensure_tables(SCHEMA)

    def get(self, key: str) -> Stored | None:
        """The stored setting ``key``, or None. DataError when its JSON cannot be read."""
        rows = self.db.rows("SELECT * FROM settings WHERE key = ?", (key,))
        return _stored(rows[0]) if rows else None

    def get_prefix(self, prefix: str) -> dict[str, Stored]:
        """Every stored setting whose key starts with ``prefix`` (by key)."""
        pattern = prefix.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_") + "%"
        rows = self.db.rows("SELECT * FROM settings WHERE key LIKE ? ESCAPE '\\' ORDER BY key", (pattern,))
        return {row["key"]: _stored(row) for row in rows}

    def put(self, key: str, value: Any, version: int = 1) -> None:  # noqa: ANN401 - any JSON
        """Store one setting (replacing it)."""
        self.write({key: value}, version=version)

    def write(
        self, values: Mapping[str, Any], deletes: Iterable[str] = (), version: int = 1
    ) -> None:
        """Store ``values`` (key → JSON value, all of shape ``version``) and remove ``deletes``,
        in one transaction. DataError (nothing written) when a value is not finite JSON."""
        encoded = {key: _encode(key, value) for key, value in values.items()}
        now = time.time()
        with self.db.transaction() as c:
            for key in deletes:
                c.execute("DELETE FROM settings WHERE key = ?", (key,))
            for key, text in encoded.items():
                c.execute(
                    "INSERT INTO settings (key, version, value, updated_s) VALUES (?, ?, ?, ?) "
                    "ON CONFLICT(key) DO UPDATE SET version = excluded.version, "
                    "value = excluded.value, updated_s = excluded.updated_s",
                    (key, int(version), text, now),
                )

    def delete(self, *keys: str) -> None:
        """Remove ``keys`` (a setting back to its default), in one transaction."""
        self.write({}, deletes=keys)


def _encode(key: str, value: Any) -> str:  # noqa: ANN401 - any JSON
    try:
        return json.dumps(value, allow_nan=False, separators=(",", ":"))
    except (TypeError, ValueError) as exc:
        raise DataError(f"setting {key!r}: not storable as JSON ({exc})") from None


def _stored(row: Any) -> Stored:  # noqa: ANN401 - a sqlite3.Row
    try:
        value = json.loads(row["value"])
    except ValueError as exc:
        raise DataError(f"setting {row['key']!r}: stored JSON unreadable ({exc})") from None
    return Stored(row["key"], int(row["version"]), value, float(row["updated_s"]))
