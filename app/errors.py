"""The ONE place where engine errors become HTTP statuses.

ConfigError → 422 (out-of-range angle, unstable gains: the message names the limit),
DataError → 400 (malformed upload: the message names the line and column),
DriverFault → 503, JobCancelled → 409, unknown axis / resource → 404 (:class:`NotFound`),
manual control held by someone else → 409 (:class:`Conflict`), missing/unknown key → 401
(:class:`Unauthorized`), role too low → 403 (:class:`Forbidden`).
Bodies are ``{"detail": str, "error": <class name>, ...extra}``.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from tracker.errors import ConfigError, DataError, DriverFault, JobCancelled, TrackerError

log = logging.getLogger("app")


class NotFound(LookupError):
    """An unknown axis, preset, measurement, version or job."""


class Conflict(RuntimeError):
    """The request clashes with the current state (another holder of manual control)."""

    def __init__(self, message: str, **extra: Any) -> None:
        super().__init__(message)
        self.extra = extra


class Unauthorized(PermissionError):
    """No API key, or one that is unknown or revoked."""


class Forbidden(PermissionError):
    """The key's role is below what the request needs."""


class Refused(ConfigError):
    """A ConfigError carrying numbers for the client (computed margins, the limit)."""

    def __init__(self, message: str, **extra: Any) -> None:
        super().__init__(message)
        self.extra = extra


AXES = ("pan", "tilt")


def check_axis(axis: str) -> str:
    """``axis`` if it is known, else NotFound (→ 404)."""
    if axis not in AXES:
        raise NotFound(f"unknown axis {axis!r}; axes: {', '.join(AXES)}")
    return axis


STATUS_BY_ERROR: tuple[tuple[type[Exception], int], ...] = (
    (Unauthorized, 401),
    (Forbidden, 403),
    (NotFound, 404),
    (Conflict, 409),
    (ConfigError, 422),
    (DataError, 400),
    (DriverFault, 503),
    (JobCancelled, 409),
    (TrackerError, 400),
)


def status_for(exc: BaseException) -> int:
    """HTTP status for an exception (500 when unknown)."""
    for cls, status in STATUS_BY_ERROR:
        if isinstance(exc, cls):
            return status
    return 500


def error_body(exc: BaseException) -> dict[str, Any]:
    """JSON body for an exception."""
    body: dict[str, Any] = {"detail": str(exc), "error": type(exc).__name__}
    body.update(getattr(exc, "extra", {}) or {})
    return body


def install(app: FastAPI) -> None:
    """Register the handlers on ``app``."""

    async def handle(request: Request, exc: Exception) -> JSONResponse:
        status = status_for(exc)
        if status >= 500 and not isinstance(exc, DriverFault):
            log.exception("unhandled error on %s %s", request.method, request.url.path)
            return JSONResponse({"detail": "internal error", "error": type(exc).__name__}, status_code=500)
        headers = {"WWW-Authenticate": "X-API-Key"} if status == 401 else None
        return JSONResponse(error_body(exc), status_code=status, headers=headers)

    for cls, _ in STATUS_BY_ERROR:
        app.add_exception_handler(cls, handle)
