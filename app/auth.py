"""API keys and roles: viewer < operator < engineer < admin; keys travel in the ``X-API-Key`` header.

Only a SHA-256 hash of each key is stored (keys are 256-bit random tokens, so a fast hash is
enough; nothing to brute-force). The first start creates an admin key and writes it, mode 0600,
to the data folder. Missing or unknown key → :class:`Unauthorized` (401); a known key whose
role is too low → :class:`Forbidden` (403); app/errors.py maps them.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import Depends, Request, WebSocket
from fastapi.security import APIKeyHeader

from app.db import Database
from app.errors import Forbidden, Unauthorized

KEY_HEADER = "X-API-Key"
KEY_PREFIX = "3dat_"


class Role(enum.IntEnum):
    """What a key may do; each role includes the ones below it."""

    viewer = 1  # read status, telemetry, presets, workbench results
    operator = 2  # tracking, pointing, jog, presets
    engineer = 3  # gains, workbench, jobs, practice rig
    admin = 4  # keys

    @classmethod
    def parse(cls, name: str) -> Role:
        try:
            return cls[name]
        except KeyError:
            raise ValueError(f"unknown role {name!r}; roles: {', '.join(r.name for r in cls)}") from None


@dataclass(frozen=True, slots=True)
class Principal:
    """Who is calling: the key's id, name and role."""

    key_id: int
    name: str
    role: Role


def hash_key(key: str) -> str:
    """The stored form of a key."""
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


def new_key() -> str:
    """A fresh random key."""
    return KEY_PREFIX + secrets.token_urlsafe(32)


def create_key(db: Database, name: str, role: Role) -> tuple[int, str]:
    """Store a new key's hash; return its id and the key (shown once, never stored)."""
    key = new_key()
    key_id = db.add_key(name, role.name, hash_key(key), key[: len(KEY_PREFIX) + 4])
    return key_id, key


def lookup(db: Database, key: str | None) -> Principal | None:
    """The principal for ``key``, or None when missing, unknown or revoked."""
    if not key:
        return None
    digest = hash_key(key.strip())
    rec = db.key_by_hash(digest)
    if rec is None or rec.revoked or not hmac.compare_digest(digest, hash_key(key.strip())):
        return None
    return Principal(rec.id, rec.name, Role.parse(rec.role))


def write_secret_file(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` readable by the owner only (0600), atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.write(fd, text.encode("utf-8"))
    finally:
        os.close(fd)
    os.chmod(tmp, 0o600)
    os.replace(tmp, path)


def ensure_admin_key(db: Database, key_path: Path) -> str | None:
    """On the first start (no keys at all) create an admin key, write it to ``key_path``.

    Returns the new key, or None when keys already exist.
    """
    if db.count_keys() > 0:
        return None
    _, key = create_key(db, "admin (first start)", Role.admin)
    write_secret_file(key_path, key + "\n")
    print(f"3DAT console: first start: admin API key written to {key_path.resolve()} (mode 0600)", flush=True)
    return key


_header = APIKeyHeader(name=KEY_HEADER, auto_error=False, description="API key (see docs/console.md)")


class RequireRole:
    """A FastAPI dependency: the caller's principal, or 401/403.

    ``role`` is readable, so the request guard (app/guard.py) refuses a request before its body
    is read; this check stays as the route's own.
    """

    def __init__(self, role: Role) -> None:
        self.role = role
        self.__name__ = f"require_{role.name}"

    def __call__(self, request: Request, key: str | None = Depends(_header)) -> Principal:
        return authorize(request.app.state.db, key, self.role)


def authorize(db: Database, key: str | None, role: Role) -> Principal:
    """The principal of ``key`` if it may act as ``role``; Unauthorized (401) or Forbidden (403)."""
    who = lookup(db, key)
    if who is None:
        detail = "missing API key" if not key else "unknown or revoked API key"
        raise Unauthorized(f"{detail} (header {KEY_HEADER})")
    if who.role < role:
        raise Forbidden(f"role {who.role.name} may not do this; needs {role.name}")
    return who


def require(role: Role) -> RequireRole:
    """The dependency that lets ``role`` and above through."""
    return RequireRole(role)


def websocket_principal(ws: WebSocket, key: str | None) -> Principal | None:
    """The principal for a WebSocket (header, or the key sent as the first message)."""
    return lookup(ws.app.state.db, key or ws.headers.get(KEY_HEADER))


Viewer = Annotated[Principal, Depends(require(Role.viewer))]
Operator = Annotated[Principal, Depends(require(Role.operator))]
Engineer = Annotated[Principal, Depends(require(Role.engineer))]
Admin = Annotated[Principal, Depends(require(Role.admin))]
