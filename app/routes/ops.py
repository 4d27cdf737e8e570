"""Outside /api/v1, for monitoring: GET /metrics (Prometheus text) and GET /health (200 or 503).

``/metrics`` needs a key of the role ``metrics_role`` (default viewer; ``public`` for none), sent
as ``X-API-Key`` or as ``Authorization: Bearer <key>`` (what Prometheus's ``authorization``
scrape option sends); unknown keys count toward the address's back-off like any other.
``/health`` needs no key (the same answer as ``/api/v1/health``).
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, Response

from app.auth import KEY_HEADER, Role, authorize
from app.errors import TooManyRequests, Unauthorized
from app.guard import client_address
from app.health import health_of
from app.metrics import CONTENT_TYPE
from app.service import Svc

router = APIRouter()


def scrape_key(request: Request) -> str | None:
    """The key of a scrape: the X-API-Key header, else an ``Authorization: Bearer`` token."""
    key = request.headers.get(KEY_HEADER)
    if key:
        return key
    scheme, _, token = request.headers.get("authorization", "").partition(" ")
    return (token.strip() or None) if scheme.lower() == "bearer" else None


@router.get("/metrics", include_in_schema=False)
async def metrics(request: Request, svc: Svc) -> Response:
    role_name = svc.settings.metrics_role
    if role_name != "public":
        address = client_address(request.scope)
        wait_s = svc.bad_keys.retry_after_s(address)
        if wait_s > 0:
            raise TooManyRequests(f"too many unknown or revoked API keys from this address; retry in "
                                  f"{wait_s:.0f} s", retry_after_s=wait_s)
        key = scrape_key(request)
        try:
            authorize(svc.db, key, Role[role_name])
        except Unauthorized:
            wait_s = svc.bad_keys.failed(address) if key else 0.0
            if wait_s > 0:
                raise TooManyRequests(f"too many unknown or revoked API keys from this address; retry "
                                      f"in {wait_s:.0f} s", retry_after_s=wait_s) from None
            raise
    return Response(svc.metrics.render(), media_type=CONTENT_TYPE)


@router.get("/health", include_in_schema=False)
async def health(svc: Svc) -> JSONResponse:
    ok, body = health_of(svc)
    return JSONResponse(body, status_code=200 if ok else 503)
