"""Controller gains per axis: read, preview (margins and predicted step response), apply.

A gain set that makes the loop unstable or puts the phase margin under the configured floor is
refused with 422 and the computed margins; nothing changes on the rig.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from fastapi import APIRouter

from app import rig
from app.auth import Engineer, Viewer
from app.errors import NotFound, Refused, check_axis
from app.modelio import model_from_json
from app.schemas import DesignModelIn, GainsIn, GainsOut, StepPreviewIn
from app.service import Service, Svc
from tracker.errors import ConfigError

router = APIRouter(tags=["gains"])


def _plain(value: Any) -> Any:  # noqa: ANN401 - any result object in, JSON-ready value out
    """JSON-ready copy of a result object (dataclass, numpy values, nested containers)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def candidate_gains(svc: Service, axis: str, changes: dict[str, float]) -> Any:
    """The axis' current gains with ``changes`` applied; 422 naming unknown fields."""
    current = svc.engine.gains(axis)
    names = [f.name for f in dataclasses.fields(current)]
    unknown = sorted(set(changes) - set(names))
    if unknown:
        raise Refused(
            f"unknown gain field(s) {', '.join(unknown)} for {type(current).__name__}; "
            f"fields: {', '.join(names)}",
            fields=names,
        )
    return dataclasses.replace(current, **changes)


def margins_of(svc: Service, axis: str, gains: Any) -> dict[str, Any]:
    """Phase/gain margins and stability of ``gains`` on the axis model (DesignReport as JSON)."""
    from tracker.control.design import check_gains

    report = check_gains(rig.axis_model(svc.engine, axis), gains, svc.settings.min_phase_margin_deg)
    out: dict[str, Any] = _plain(report)
    floor = svc.settings.min_phase_margin_deg
    pm = out.get("phase_margin_deg")
    out["acceptable"] = bool(out.get("stable")) and pm is not None and pm >= floor
    return out


def step_of(
    svc: Service, axis: str, gains: Any, amplitude_deg: float, duration_s: float, shaped: bool = True
) -> dict[str, Any]:
    """Predicted step response, as {"t_s": [...], "angle_deg": [...], figures} (decimated)."""
    res = rig.step_response(svc.engine, axis, gains, math.radians(amplitude_deg), duration_s, shaped)
    t, y = res.pop("t_s"), res.pop("angle_rad")
    step = max(1, len(t) // 400)
    out: dict[str, Any] = _plain(
        {
            **res,
            "t_s": t[::step].round(5),
            "angle_deg": (y[::step] * 180.0 / math.pi).round(4),
            "amplitude_deg": amplitude_deg,
        }
    )
    return out


@router.get(
    "/axes/{axis}/gains", response_model=GainsOut, summary="Current gains of an axis and their margins"
)
async def get_gains(axis: str, svc: Svc, who: Viewer) -> GainsOut:
    check_axis(axis)
    return _gains_out(svc, axis)


@router.post(
    "/axes/{axis}/gains/preview",
    summary="Margins and predicted step response of a gain set (nothing applied)",
)
async def preview_gains(axis: str, body: StepPreviewIn, svc: Svc, who: Viewer) -> dict[str, Any]:
    check_axis(axis)
    current = svc.engine.gains(axis)
    cand = candidate_gains(svc, axis, body.gains)
    return {
        "axis": axis,
        "gains": _plain(cand),
        "margins": margins_of(svc, axis, cand),
        "step": step_of(svc, axis, cand, body.amplitude_deg, body.duration_s, body.shaped),
        "current_step": step_of(svc, axis, current, body.amplitude_deg, body.duration_s, body.shaped),
        "min_phase_margin_deg": svc.settings.min_phase_margin_deg,
    }


@router.put(
    "/axes/{axis}/gains", response_model=GainsOut, summary="Apply gains (422 with margins when unsafe)"
)
async def put_gains(axis: str, body: GainsIn, svc: Svc, who: Engineer) -> GainsOut:
    check_axis(axis)
    cand = candidate_gains(svc, axis, body.gains)
    margins = margins_of(svc, axis, cand)
    floor = svc.settings.min_phase_margin_deg
    if not margins["acceptable"]:
        why = "unstable" if not margins.get("stable") else f"phase margin under the {floor:g}° floor"
        raise Refused(
            f"gains refused for {axis}: {why} (phase margin {margins.get('phase_margin_deg')}°, "
            f"gain margin {margins.get('gain_margin_db')} dB)",
            margins=margins,
            min_phase_margin_deg=floor,
        )
    svc.engine.set_gains(axis, cand)
    gains = svc.engine.gains(axis)
    return GainsOut(
        axis=axis,  # type: ignore[arg-type]  # checked by check_axis
        gains=_plain(gains) | {"type": type(gains).__name__},
        margins=margins_of(svc, axis, gains),
        min_phase_margin_deg=floor,
    )


@router.put(
    "/axes/{axis}/model",
    response_model=GainsOut,
    summary="Redesign the axis controller on a workbench model version (422 with margins when refused)",
)
async def put_model(axis: str, body: DesignModelIn, svc: Svc, who: Engineer) -> GainsOut:
    check_axis(axis)
    version = svc.db.get_version(body.version_id)
    if version is None:
        raise NotFound(f"no model version {body.version_id}")
    if version["model"]["axis"] != axis:
        raise Refused(f"version {body.version_id} models the {version['model']['axis']} axis, not {axis}")
    try:
        svc.engine.set_model(axis, model_from_json(version["model"]))
    except ConfigError as exc:
        raise Refused(str(exc)) from None
    return _gains_out(svc, axis)


def _gains_out(svc: Service, axis: str) -> GainsOut:
    """The axis's current gains, their margins and the configured floor."""
    gains = svc.engine.gains(axis)
    return GainsOut(
        axis=axis,  # type: ignore[arg-type]  # checked by check_axis
        gains=_plain(gains) | {"type": type(gains).__name__},
        margins=margins_of(svc, axis, gains),
        min_phase_margin_deg=svc.settings.min_phase_margin_deg,
    )
