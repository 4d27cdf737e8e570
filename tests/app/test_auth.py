"""Roles and keys: 401 without a valid key, 403 below the needed role, hashes only at rest."""

from __future__ import annotations

import stat

import pytest

from app.auth import Role, create_key, hash_key, lookup
from app.db import Database

from .conftest import Rig

API = "/api/v1"


def test_first_start_wrote_the_admin_key_owner_only(rig: Rig) -> None:
    key_file = rig.data_dir / "admin.key"
    assert stat.S_IMODE(key_file.stat().st_mode) == 0o600
    me = rig.client.get(f"{API}/whoami", headers={"X-API-Key": key_file.read_text().strip()}).json()
    assert me["role"] == "admin"


def test_only_hashes_are_stored(rig: Rig) -> None:
    raw = b"".join(p.read_bytes() for p in rig.data_dir.glob("console.sqlite3*"))
    for key in rig.keys.values():
        assert key.encode() not in raw
    assert any(
        hash_key(rig.keys["operator"]).encode() in p.read_bytes()
        for p in rig.data_dir.glob("console.sqlite3*")
    )


@pytest.mark.parametrize("headers", [{}, {"X-API-Key": "3dat_not-a-real-key"}], ids=["missing", "unknown"])
def test_no_valid_key_is_401(rig: Rig, headers: dict[str, str]) -> None:
    r = rig.client.get(f"{API}/status", headers=headers)
    assert r.status_code == 401
    assert "X-API-Key" in r.json()["detail"]


@pytest.mark.parametrize(
    ("role", "method", "path", "body"),
    [
        ("viewer", "PUT", "/tracking", {"enabled": False}),
        ("viewer", "PUT", "/pointing", {"pan_deg": 0, "tilt_deg": 0}),
        ("viewer", "PUT", "/presets/x", {}),
        ("operator", "PUT", "/axes/pan/gains", {"gains": {}}),
        ("operator", "POST", "/jobs/friction-id", {"axis": "pan"}),
        ("operator", "POST", "/practice", {"axis": "pan"}),
        ("engineer", "GET", "/keys", None),
        ("engineer", "POST", "/keys", {"name": "x", "role": "viewer"}),
    ],
    ids=lambda v: v if isinstance(v, str) else "",
)
def test_role_below_the_need_is_403(rig: Rig, role: str, method: str, path: str, body: object) -> None:
    r = rig.client.request(method, f"{API}{path}", headers=rig.h(role), json=body)
    assert r.status_code == 403, r.text
    assert role in r.json()["detail"]


def test_admin_creates_and_revokes_a_key(rig: Rig) -> None:
    r = rig.client.post(
        f"{API}/keys", headers=rig.h("admin"), json={"name": "room control", "role": "operator"}
    )
    assert r.status_code == 201
    new = r.json()
    assert new["key"].startswith("3dat_")
    assert rig.client.get(f"{API}/whoami", headers={"X-API-Key": new["key"]}).json()["role"] == "operator"
    listed = rig.client.get(f"{API}/keys", headers=rig.h("admin")).json()
    assert all(k.get("key") is None for k in listed)
    assert rig.client.delete(f"{API}/keys/{new['id']}", headers=rig.h("admin")).status_code == 204
    assert rig.client.get(f"{API}/whoami", headers={"X-API-Key": new["key"]}).status_code == 401


def test_bad_role_name_is_422(rig: Rig) -> None:
    r = rig.client.post(f"{API}/keys", headers=rig.h("admin"), json={"name": "x", "role": "superuser"})
    assert r.status_code == 422


def test_lookup_rejects_revoked_keys(tmp_path) -> None:  # type: ignore[no-untyped-def]
    db = Database(tmp_path / "k.sqlite3")
    key_id, key = create_key(db, "k", Role.engineer)
    assert lookup(db, key) is not None and lookup(db, key).role is Role.engineer  # type: ignore[union-attr]
    db.revoke_key(key_id)
    assert lookup(db, key) is None
    assert lookup(db, "") is None


def test_the_last_admin_key_cannot_be_revoked(rig: Rig) -> None:
    me = rig.client.get(f"{API}/whoami", headers=rig.h("admin")).json()
    r = rig.client.delete(f"{API}/keys/{me['key_id']}", headers=rig.h("admin"))
    assert r.status_code == 409 and "last active admin" in r.json()["detail"]
    assert rig.client.get(f"{API}/whoami", headers=rig.h("admin")).status_code == 200
    assert rig.client.delete(f"{API}/keys/99999", headers=rig.h("admin")).status_code == 404
