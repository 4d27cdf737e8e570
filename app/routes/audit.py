"""GET /audit (admins): who changed what on the rig, newest first, a page at a time (app/audit.py)."""

from __future__ import annotations

from dataclasses import asdict
from typing import Annotated, Any

from fastapi import APIRouter, Query

from app.auth import Admin
from app.service import Svc

router = APIRouter(tags=["audit"])


@router.get("/audit", summary="The audit log, newest first (admins); page with before_id")
async def get_audit(
    svc: Svc,
    who: Admin,
    limit: Annotated[int, Query(ge=1, le=500, description="entries per page")] = 50,
    before_id: Annotated[int | None, Query(ge=1, le=2**62, description="entries older than this id "
                                           "(the previous page's next_before_id)")] = None,
) -> dict[str, Any]:
    entries = svc.audit.page(limit, before_id)
    more = len(entries) == limit
    return {
        "entries": [asdict(e) for e in entries],
        "next_before_id": entries[-1].id if more else None,
    }
