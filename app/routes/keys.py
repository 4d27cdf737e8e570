"""API keys (admin): list, create (the key is shown once), revoke (live sessions too); GET /whoami."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from app.auth import Admin, Role, Viewer, create_key
from app.errors import Conflict, NotFound
from app.schemas import KeyIn, KeyOut, RowId
from app.service import Svc

router = APIRouter(tags=["keys"])


@router.get("/whoami", summary="The calling key's name and role")
async def whoami(svc: Svc, who: Viewer) -> dict[str, Any]:
    return {
        "name": who.name,
        "role": who.role.name,
        "key_id": who.key_id,
        "roles": [r.name for r in Role if r <= who.role],
    }


@router.get("/keys", response_model=list[KeyOut], summary="List keys (hashes are never shown)")
async def list_keys(svc: Svc, who: Admin) -> list[KeyOut]:
    return [
        KeyOut(id=k.id, name=k.name, role=k.role, prefix=k.prefix, revoked=k.revoked, key=None)
        for k in svc.db.list_keys()
    ]


@router.post(
    "/keys", response_model=KeyOut, status_code=201, summary="Create a key; the response holds it once"
)
async def post_key(body: KeyIn, svc: Svc, who: Admin) -> KeyOut:
    key_id, key = create_key(svc.db, body.name, Role.parse(body.role))
    await svc.audit.record(who, "key.create", str(key_id), {"name": body.name, "role": body.role})
    return KeyOut(id=key_id, name=body.name, role=body.role, prefix=key[:9], revoked=False, key=key)


@router.delete(
    "/keys/{key_id}",
    status_code=204,
    summary="Revoke a key (its telemetry WebSockets close with 4401, its manual control is freed)",
)
async def delete_key(key_id: RowId, svc: Svc, who: Admin) -> None:
    keys = {k.id: k for k in svc.db.list_keys()}
    if key_id not in keys:
        raise NotFound(f"no key {key_id}")
    admins = [k for k in keys.values() if k.role == "admin" and not k.revoked]
    if keys[key_id].role == "admin" and [k.id for k in admins] == [key_id]:
        raise Conflict("this is the last active admin key; create another admin key before revoking it")
    svc.revoke_key(key_id)
    revoked = keys[key_id]
    await svc.audit.record(who, "key.revoke", str(key_id), {"name": revoked.name, "role": revoked.role})
