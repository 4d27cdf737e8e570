"""Manual pointing: PUT /pointing (hold a direction), DELETE /pointing (release), jog press/release.

Pointing and jogging take manual control (one holder at a time; 409 names the holder); while a
drive fault is latched they are refused with 503 (DriverFault) until an engineer clears it
(``POST /faults/clear``); releasing and stopping a jog stay allowed. A jog
is a rate command that the engine stops by itself after ``jog_timeout_s`` unless pressed again:
the console re-sends the press every 150 ms while the button is down and sends the release on
mouse-up, so a lost connection or a closed tab stops the axis within the timeout.
"""

from __future__ import annotations

import math

from fastapi import APIRouter

from app.auth import Operator
from app.errors import Refused, check_axis
from app.rig import check_angle
from app.schemas import JogIn, JogOut, PointingIn, PointingOut
from app.service import Service, Svc
from tracker.errors import ConfigError

router = APIRouter(tags=["pointing"])


def point_deg(svc: Service, pan_deg: float, tilt_deg: float) -> None:
    """Point the camera (degrees); 422 naming the limit when out of range."""
    limits = svc.limits_deg()
    for axis, value in (("pan", pan_deg), ("tilt", tilt_deg)):
        try:
            check_angle(axis, value, limits[axis])
        except ConfigError as exc:
            raise Refused(str(exc), axis=axis, value_deg=value, limit_deg=limits[axis]) from None
    svc.engine.point(math.radians(pan_deg), math.radians(tilt_deg))


@router.put("/pointing", response_model=PointingOut, summary="Point the camera (manual override)")
async def put_pointing(body: PointingIn, svc: Svc, who: Operator) -> PointingOut:
    svc.engine.require_no_fault()
    svc.lock.acquire(who)
    point_deg(svc, body.pan_deg, body.tilt_deg)
    await svc.audit.record(who, "pointing.set", "", {"pan_deg": body.pan_deg, "tilt_deg": body.tilt_deg})
    return PointingOut(
        pan_target_deg=body.pan_deg,
        tilt_target_deg=body.tilt_deg,
        mode=str(svc.engine.status().mode),
        control_holder=svc.lock.describe(),
    )


@router.delete("/pointing", summary="Release manual control (tracking resumes if it is on)")
async def delete_pointing(svc: Svc, who: Operator) -> dict[str, object]:
    svc.lock.release(who)
    svc.engine.release()
    await svc.audit.record(who, "pointing.release")
    st = svc.engine.status()
    return {"mode": str(st.mode), "tracking": bool(st.tracking), "control_holder": svc.lock.describe()}


@router.put(
    "/jog/{axis}", response_model=JogOut, summary="Jog press: move at a rate until released or timeout"
)
async def put_jog(axis: str, body: JogIn, svc: Svc, who: Operator) -> JogOut:
    check_axis(axis)
    if body.rate_deg_s != 0.0:
        svc.engine.require_no_fault()
    svc.lock.acquire(who)
    timeout_s = svc.settings.jog_timeout_s
    svc.engine.jog(axis, math.radians(body.rate_deg_s), timeout_s=timeout_s)
    await svc.audit.record(who, "jog.start" if body.rate_deg_s else "jog.stop", axis,  # renewals coalesce
                     {"rate_deg_s": body.rate_deg_s} if body.rate_deg_s else None)
    return JogOut(axis=axis, rate_deg_s=body.rate_deg_s, auto_stop_s=timeout_s)  # type: ignore[arg-type]


@router.delete("/jog/{axis}", response_model=JogOut, summary="Jog release: stop the axis")
async def delete_jog(axis: str, svc: Svc, who: Operator) -> JogOut:
    check_axis(axis)
    svc.lock.acquire(who)
    svc.engine.jog(axis, 0.0, timeout_s=svc.settings.jog_timeout_s)
    await svc.audit.record(who, "jog.stop", axis)
    return JogOut(axis=axis, rate_deg_s=0.0, auto_stop_s=0.0)  # type: ignore[arg-type]


@router.post("/control", summary="Take manual control (engineers may take it over with force=true)")
async def take_control(svc: Svc, who: Operator, force: bool = False) -> dict[str, object]:
    svc.lock.acquire(who, force=force)
    await svc.audit.record(who, "control.take", "", {"force": force})
    return {"control_holder": svc.lock.describe()}


@router.delete("/control", summary="Give manual control back without moving")
async def give_control(svc: Svc, who: Operator) -> dict[str, object]:
    svc.lock.release(who)
    await svc.audit.record(who, "control.give")
    return {"control_holder": svc.lock.describe()}
