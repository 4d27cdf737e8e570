"""The ONE place where engine errors become HTTP statuses.

ConfigError → 422 (out-of-range angle, unstable gains: the message names the limit),
DataError → 400 (malformed upload: the message names the line and column),
DriverFault → 503, JobCancelled → 409, unknown axis / resource → 404 (:class:`NotFound`),
manual control held by someone else → 409 (:class:`Conflict`), missing/unknown key → 401
(:class:`Unauthorized`), role too low → 403 (:class:`Forbidden`), a body, upload or measurement
over its cap → 413 (:class:`TooLarge`), a worker process lost → 503 (:class:`Unavailable`),
too many bad keys or too much heavy work at once → 429
with ``Retry-After`` (:class:`TooManyRequests`), a request that fails validation → 422 (its
input shortened, never echoed whole), anything else → 500 (logged; the body says only
"internal error").
Bodies are always JSON ``{"detail": str, "error": <kind>, ...extra}``.
"""

from __future__ import annotations

import http
import logging
import math
import reprlib
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException

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


class TooLarge(DataError):
    """A request body, an upload or a measurement over its cap; ``extra`` names the cap."""

    def __init__(self, message: str, **extra: Any) -> None:
        super().__init__(message)
        self.extra = extra


class TooManyRequests(RuntimeError):
    """Too many bad keys from one address, or too much heavy work at once; retry later."""

    def __init__(self, message: str, retry_after_s: float) -> None:
        super().__init__(message)
        self.retry_after_s = max(1, math.ceil(retry_after_s))
        self.extra = {"retry_after_s": self.retry_after_s}


class Unavailable(RuntimeError):
    """The service cannot do it now (a worker process died); retrying may work."""


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
    (TooLarge, 413),
    (TooManyRequests, 429),
    (ConfigError, 422),
    (DataError, 400),
    (DriverFault, 503),
    (Unavailable, 503),
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
    body.update(_finite(getattr(exc, "extra", {}) or {}))
    return body


def _finite(value: Any) -> Any:  # noqa: ANN401 - nested JSON-like value in and out
    """``value`` with non-finite floats as None (JSON has no NaN; the encoder would fail)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def error_response(exc: BaseException) -> JSONResponse:
    """The JSON response for an exception of the tree (500 "internal error" when unknown)."""
    status = status_for(exc)
    if status == 500:
        return JSONResponse({"detail": "internal error", "error": type(exc).__name__}, status_code=500)
    headers: dict[str, str] = {}
    if status == 401:
        headers["WWW-Authenticate"] = "X-API-Key"
    if isinstance(exc, TooManyRequests):
        headers["Retry-After"] = str(exc.retry_after_s)
    return JSONResponse(error_body(exc), status_code=status, headers=headers or None)


MAX_ERRORS_SHOWN = 20
_short_repr = reprlib.Repr()  # Python 3.11's Repr takes no arguments
_short_repr.maxlevel, _short_repr.maxstring, _short_repr.maxother = 2, 60, 60
_short_repr.maxdict = _short_repr.maxlist = _short_repr.maxtuple = _short_repr.maxset = 4
_SHORT_STR = 200


def short(value: Any) -> Any:  # noqa: ANN401 - any input in, a small JSON-safe value out
    """A JSON-safe, bounded stand-in for ``value``: small scalars as they are, non-finite floats,
    huge integers, long strings and containers as short strings (a 422 never echoes a big input,
    and NaN cannot break the JSON encoder)."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value if abs(value) < 2**63 else _short_repr.repr(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if isinstance(value, str):
        return value if len(value) <= _SHORT_STR else value[:_SHORT_STR] + f"... ({len(value)} characters)"
    return _short_repr.repr(value)


def validation_body(exc: RequestValidationError) -> dict[str, Any]:
    """The 422 body: a one-line summary and the first errors with their inputs shortened."""
    errors = list(exc.errors())
    shown = [
        {
            "loc": [short(x) for x in e.get("loc", ())],
            "msg": str(e.get("msg", "")),
            "type": str(e.get("type", "")),
            "input": short(e.get("input")),
            **({"ctx": {str(k): short(v) for k, v in e["ctx"].items()}} if e.get("ctx") else {}),
        }
        for e in errors[:MAX_ERRORS_SHOWN]
    ]
    parts = [f"{'.'.join(str(x) for x in e['loc'])}: {e['msg']}" for e in shown[:3]]
    more = len(errors) - min(len(errors), 3)
    detail = "; ".join(parts) + (f" (and {more} more)" if more else "")
    body: dict[str, Any] = {"detail": detail or "invalid request", "error": "ValidationError"}
    body["errors"] = shown
    if len(errors) > MAX_ERRORS_SHOWN:
        body["errors_total"] = len(errors)
    return body


def install(app: FastAPI) -> None:
    """Register the handlers on ``app``: the tree, validation, HTTP errors and a catch-all."""

    async def handle(request: Request, exc: Exception) -> JSONResponse:
        if status_for(exc) == 500:
            log.error("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
        return error_response(exc)

    async def handle_validation(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        return JSONResponse(validation_body(exc), status_code=422)

    async def handle_http(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, HTTPException)
        phrase = http.HTTPStatus(exc.status_code).phrase
        detail = exc.detail if isinstance(exc.detail, str) else phrase
        return JSONResponse(
            {"detail": detail, "error": phrase.title().replace(" ", "").replace("-", "")},
            status_code=exc.status_code,
            headers=exc.headers,
        )

    for cls, _ in STATUS_BY_ERROR:
        app.add_exception_handler(cls, handle)
    app.add_exception_handler(RequestValidationError, handle_validation)
    app.add_exception_handler(HTTPException, handle_http)
    app.add_exception_handler(Exception, handle)  # the catch-all: JSON 500, never plain text
