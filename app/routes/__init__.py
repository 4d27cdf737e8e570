"""REST and WebSocket routes, one module per resource; all mounted under /api/v1."""

from __future__ import annotations

from app.routes import (
    audio,
    audit,
    gains,
    jobs,
    keys,
    pointing,
    practice,
    presets,
    status,
    telemetry,
    tracking,
    view,
    workbench,
)

ALL_ROUTERS = (
    status.router,
    tracking.router,
    audio.router,
    pointing.router,
    presets.router,
    gains.router,
    workbench.router,
    jobs.router,
    practice.router,
    telemetry.router,
    keys.router,
    audit.router,
    view.router,
)
