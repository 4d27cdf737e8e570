"""GET /status: where the camera points, what it is doing, who holds manual control, how well the
control loop keeps its clock; GET /viewer."""

from __future__ import annotations

import math
from typing import Any

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from app import rig
from app.auth import Engineer, Viewer
from app.health import health_of
from app.routes.audio import talkers_of
from app.schemas import LoopOut, StatusOut
from app.service import Service, Svc

router = APIRouter(tags=["status"])


def status_of(svc: Service) -> StatusOut:
    """The engine's status in degrees, with the service's own view (control holder, viewers)."""
    st = svc.engine.status()
    return StatusOut(
        t_s=float(st.t_s),
        pan_deg=math.degrees(st.pan_rad),
        tilt_deg=math.degrees(st.tilt_rad),
        pan_target_deg=math.degrees(st.pan_target_rad),
        tilt_target_deg=math.degrees(st.tilt_target_rad),
        mode=str(st.mode),
        tracking=bool(st.tracking),
        active_talker=st.active_talker,
        faults=[str(f) for f in st.faults],
        control_holder=svc.lock.describe(),
        limits_deg=svc.limits_deg(),
        telemetry_clients=svc.hub.clients,
        audio=audio_state(svc),
        audio_capture=capture_of(svc),
        talkers=talkers_of(svc),
        viewer=svc.viewer.scene_state() if svc.viewer is not None else None,
        driver=rig.driver_state(svc.engine),
        loop=loop_of(svc),
        settings_warnings=list(svc.console.warnings),
    )


def loop_of(svc: Service) -> LoopOut | None:
    """The engine loop's timing in milliseconds."""
    timing = getattr(svc.engine, "timing", None)
    if timing is None:
        return None
    t = timing()
    age_s = getattr(t, "last_tick_age_s", math.inf)
    return LoopOut(period_ms=1e3 * t.period_s, ticks=t.ticks, last_lateness_ms=1e3 * t.last_lateness_s,
                   max_lateness_ms=1e3 * t.max_lateness_s, mean_lateness_ms=1e3 * t.mean_lateness_s,
                   overruns=t.overruns, restarts=t.restarts, in_thread=t.in_thread, priority=t.priority,
                   service_threads_priority=svc.threads_priority,
                   warm_up_ticks=getattr(t, "warm_up_ticks", 0),
                   warm_up_max_lateness_ms=1e3 * getattr(t, "warm_up_max_lateness_s", 0.0),
                   last_tick_ms_ago=1e3 * age_s if math.isfinite(age_s) else None)


@router.get("/status", response_model=StatusOut, summary="Angles (deg), mode, tracking, talker, faults")
async def get_status(svc: Svc, who: Viewer) -> StatusOut:
    return status_of(svc)


@router.get("/viewer", summary="The 3D view: its address and what its scene shows now")
async def get_viewer(svc: Svc, who: Viewer) -> dict[str, Any]:
    if svc.viewer is None:
        return {
            "enabled": False,
            "note": "the 3D view is disabled (TRACKER_VIEWER_ENABLED) or failed to start",
        }
    return {"enabled": True, **svc.viewer.scene_state()}


@router.get(
    "/health",
    summary="Health (no key needed): 200, or 503 with the reasons when the control loop is stalled "
    "or stopped or the drive is faulted",
    responses={503: {"description": "unhealthy: `reasons` says why"}},
)
async def health(svc: Svc) -> JSONResponse:
    ok, body = health_of(svc)
    return JSONResponse(body | {"audio": audio_state(svc)}, status_code=200 if ok else 503)


def audio_state(svc: Service) -> str:
    """ "off", "ready", "preparing ...", why audio is unavailable, or live capture's fault."""
    capture = capture_of(svc)
    if capture is not None and capture["state"] == "fault":
        retry = capture.get("retry_in_s")
        again = f"; next try in {retry:.1f} s" if retry is not None else ""
        return f"live capture fault: {capture['fault']}{again}"
    return str(svc.audio_note or (getattr(svc.audio, "note", "on") if svc.audio is not None else "off"))


def capture_of(svc: Service) -> dict[str, Any] | None:
    """Live capture's status (None for other inputs)."""
    state = getattr(svc.audio, "capture_state", None)
    out: dict[str, Any] | None = state() if callable(state) else None
    return out


@router.post(
    "/faults/clear", response_model=StatusOut, summary="Clear latched driver faults and re-enable the drive"
)
async def clear_faults(svc: Svc, who: Engineer) -> StatusOut:
    """503 (DriverFault) when the drive refuses to re-enable."""
    driver = svc.engine.driver
    faults = list(driver.faults())
    driver.clear_faults()
    driver.enable()
    await svc.audit.record(who, "faults.clear", "", {"faults": faults})
    return status_of(svc)
