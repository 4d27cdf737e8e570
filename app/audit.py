"""The audit log: who (key id, name, role) changed what on the rig, and when, kept in SQLite.

Routes write an entry after a change succeeded (a refused request changes nothing and is not
logged here; the access log has it). An entry holds the action (``"pointing.set"``,
``"gains.set"``, ``"key.create"`` ...), its target (an axis, a preset's name, a key's id) and a
small JSON detail of the values asked for. Never a secret: a string that looks like an API key
(``3dat_...``) or a field named like one is replaced by ``"[redacted]"`` before it is stored.

A jog press is re-sent every 150 ms while the button is down: an entry identical to the same
key's previous one (action, target, detail) within ``coalesce_s`` is not stored again. The log
keeps the newest ``max_rows`` entries (older ones are trimmed every 1 000 writes). Each entry
also goes to the service's log (logger ``app.audit``, INFO), so the journal says which key did what.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from app.auth import KEY_PREFIX, Principal
from app.db import Database

log = logging.getLogger("app.audit")

SCHEMA = """
CREATE TABLE IF NOT EXISTS audit (
    id INTEGER PRIMARY KEY,
    t_s REAL NOT NULL,
    key_id INTEGER NOT NULL,
    key_name TEXT NOT NULL,
    role TEXT NOT NULL,
    action TEXT NOT NULL,
    target TEXT NOT NULL,
    detail TEXT NOT NULL
);
"""
SECRET_NAMES = ("key", "api_key", "secret", "token", "password", "hash", "key_hash")
REDACTED = "[redacted]"
TRIM_EVERY = 1000


@dataclass(frozen=True, slots=True)
class AuditEntry:
    """One stored entry (``t_s``: Unix time)."""

    id: int
    t_s: float
    key_id: int
    key_name: str
    role: str
    action: str
    target: str
    detail: dict[str, Any]


def scrub(value: Any) -> Any:  # noqa: ANN401 - JSON-like in, JSON-like out
    """``value`` with anything secret-looking replaced by ``REDACTED`` (see the module docstring)."""
    if isinstance(value, Mapping):
        return {str(k): REDACTED if str(k).lower() in SECRET_NAMES else scrub(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [scrub(v) for v in value]
    if isinstance(value, str) and KEY_PREFIX in value:
        return REDACTED
    if isinstance(value, float) and value != value:
        return None
    return value


class AuditLog:
    """The ``audit`` table (see the module docstring)."""

    def __init__(self, db: Database, coalesce_s: float = 2.0, max_rows: int = 100_000) -> None:
        self.db = db
        self.coalesce_s = coalesce_s
        self.max_rows = max_rows
        self._last: dict[int, tuple[tuple[str, str, str], float]] = {}  # key id -> (entry, time)
        self._writes = 0
        db.ensure_tables(SCHEMA)

    async def record(
        self, who: Principal, action: str, target: str = "", detail: Mapping[str, Any] | None = None
    ) -> bool:
        """Store an entry for ``who``; False when it repeats that key's previous one (coalesced).

        The write (an fsync: about 5 ms on this machine's disk) runs in a thread, so the event
        loop serves other requests meanwhile; it has landed when this returns."""
        text = json.dumps(scrub(dict(detail or {})), separators=(",", ":"), sort_keys=True, default=str)
        now = time.time()
        entry = (action, str(target), text)
        last = self._last.get(who.key_id)
        if last is not None and last[0] == entry and now - last[1] < self.coalesce_s:
            self._last[who.key_id] = (entry, now)
            return False
        await asyncio.to_thread(self._insert, who, entry, now)
        self._last[who.key_id] = (entry, now)
        log.info("audit: %s (%s, key %d) %s %s %s", who.name, who.role.name, who.key_id, action, target, text)
        return True

    def _insert(self, who: Principal, entry: tuple[str, str, str], now: float) -> None:
        action, target, text = entry
        with self.db.transaction() as c:
            c.execute(
                "INSERT INTO audit (t_s, key_id, key_name, role, action, target, detail) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (now, who.key_id, who.name, who.role.name, action, target, text),
            )
            self._writes += 1
            if self._writes % TRIM_EVERY == 0:
                c.execute("DELETE FROM audit WHERE id <= (SELECT MAX(id) FROM audit) - ?", (self.max_rows,))

    def page(self, limit: int = 50, before_id: int | None = None) -> list[AuditEntry]:
        """Up to ``limit`` entries, newest first, older than entry ``before_id`` when given."""
        if before_id is None:
            rows = self.db.rows("SELECT * FROM audit ORDER BY id DESC LIMIT ?", (limit,))
        else:
            rows = self.db.rows(
                "SELECT * FROM audit WHERE id < ? ORDER BY id DESC LIMIT ?", (before_id, limit))
        return [
            AuditEntry(int(r["id"]), float(r["t_s"]), int(r["key_id"]), r["key_name"], r["role"],
                       r["action"], r["target"], json.loads(r["detail"]))
            for r in rows
        ]
