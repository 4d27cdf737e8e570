"""Presets: named camera directions to store, list, recall and delete."""

from __future__ import annotations

import math
from typing import Annotated

from fastapi import APIRouter, Path

from app.auth import Operator, Viewer
from app.errors import NotFound, Refused
from app.rig import check_angle
from app.routes.pointing import point_deg
from app.schemas import NAME_PATTERN, PointingOut, PresetIn, PresetOut
from app.service import Svc
from tracker.errors import ConfigError

router = APIRouter(tags=["presets"])
PresetName = Annotated[str, Path(pattern=NAME_PATTERN, description="letters, digits, space, _ . -")]


@router.get("/presets", response_model=list[PresetOut], summary="List presets")
async def list_presets(svc: Svc, who: Viewer) -> list[PresetOut]:
    return [PresetOut(**p) for p in svc.db.list_presets()]


@router.put(
    "/presets/{name}",
    response_model=PresetOut,
    summary="Store a preset (default: where the camera points now)",
)
async def put_preset(name: PresetName, body: PresetIn, svc: Svc, who: Operator) -> PresetOut:
    st = svc.engine.status()
    pan = body.pan_deg if body.pan_deg is not None else math.degrees(st.pan_rad)
    tilt = body.tilt_deg if body.tilt_deg is not None else math.degrees(st.tilt_rad)
    limits = svc.limits_deg()
    for axis, value in (("pan", pan), ("tilt", tilt)):
        try:
            check_angle(axis, value, limits[axis])
        except ConfigError as exc:
            raise Refused(str(exc), axis=axis, value_deg=value, limit_deg=limits[axis]) from None
    svc.db.put_preset(name, round(pan, 4), round(tilt, 4))
    await svc.audit.record(who, "preset.store", name, {"pan_deg": round(pan, 4), "tilt_deg": round(tilt, 4)})
    return PresetOut(name=name, pan_deg=round(pan, 4), tilt_deg=round(tilt, 4))


@router.post("/presets/{name}/recall", response_model=PointingOut, summary="Point the camera at a preset")
async def recall_preset(name: PresetName, svc: Svc, who: Operator) -> PointingOut:
    p = svc.db.get_preset(name)
    if p is None:
        raise NotFound(f"no preset {name!r}")
    svc.engine.require_no_fault()  # 503 while a drive fault is latched
    svc.lock.acquire(who)
    point_deg(svc, p["pan_deg"], p["tilt_deg"])
    await svc.audit.record(who, "preset.recall", name, {"pan_deg": p["pan_deg"], "tilt_deg": p["tilt_deg"]})
    return PointingOut(
        pan_target_deg=p["pan_deg"],
        tilt_target_deg=p["tilt_deg"],
        mode=str(svc.engine.status().mode),
        control_holder=svc.lock.describe(),
    )


@router.delete("/presets/{name}", status_code=204, summary="Delete a preset")
async def delete_preset(name: PresetName, svc: Svc, who: Operator) -> None:
    if not svc.db.delete_preset(name):
        raise NotFound(f"no preset {name!r}")
    await svc.audit.record(who, "preset.delete", name)
