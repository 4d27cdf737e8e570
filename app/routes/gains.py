"""Controller gains per axis: read, preview (margins and predicted step response), apply.

A gain set that makes the loop unstable or puts the phase margin under the configured floor is
refused with 422 and the computed margins; nothing changes on the rig. Margins and predicted
steps are computed in the worker processes (app/heavy.py), not on the engine's event loop; a set
the design cannot evaluate (a gain of 1e308 overflows it) is refused with 422 naming the fields.
A model offered for the redesign must first predict the axis's recent motion (tracker.model_check,
in a worker process too): 422 with the figures (``model_check``, in degrees) when it does not.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np
from fastapi import APIRouter

from app import heavy, rig
from app.auth import Engineer, Principal, Viewer
from app.errors import NotFound, Refused, check_axis
from app.modelio import model_from_json, model_to_json
from app.schemas import DesignModelIn, GainsIn, GainsOut, StepPreviewIn
from app.service import Service, Svc
from tracker.errors import ConfigError, ModelRefused, TrackerError
from tracker.model_check import ModelCheck

router = APIRouter(tags=["gains"])


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


@contextmanager
def evaluable(axis: str, changes: dict[str, float]) -> Iterator[None]:
    """Turn the design's numerical failures on absurd gains into 422 naming the changed fields."""
    try:
        yield
    except TrackerError:
        raise
    except (np.linalg.LinAlgError, ValueError, ArithmeticError) as exc:
        named = ", ".join(f"{k}={v:g}" for k, v in sorted(changes.items())) or "the current gains"
        raise Refused(
            f"gains {named} for {axis} cannot be evaluated ({type(exc).__name__}: {exc})",
            fields=sorted(changes),
        ) from None


def _model_json(svc: Service, axis: str) -> dict[str, Any]:
    return model_to_json(rig.axis_model(svc.engine, axis), axis)


_MARGINS: dict[str, dict[str, Any]] = {}  # margins of recent (model, gains, floor): ~0.2 s of CPU each


async def margins_of(svc: Service, who: Principal, axis: str, gains: Any) -> dict[str, Any]:  # noqa: ANN401
    """Phase/gain margins and stability of ``gains`` on the axis model (DesignReport as JSON).

    Remembered per model, gains and floor: a console polling GET /axes/{axis}/gains would
    otherwise keep a worker busy (and get 429s) redoing python-control's analysis."""
    floor = svc.settings.min_phase_margin_deg
    model_json = _model_json(svc, axis)
    key = repr((model_json, gains, floor))
    cached = _MARGINS.get(key)
    if cached is not None:
        return dict(cached)
    out: dict[str, Any] = await svc.work.run(who, heavy.gain_margins, model_json, gains, floor)
    if len(_MARGINS) >= 64:
        _MARGINS.clear()
    _MARGINS[key] = dict(out)
    return out


@router.get(
    "/axes/{axis}/gains", response_model=GainsOut, summary="Current gains of an axis and their margins"
)
async def get_gains(axis: str, svc: Svc, who: Viewer) -> GainsOut:
    check_axis(axis)
    return await _gains_out(svc, who, axis)


@router.post(
    "/axes/{axis}/gains/preview",
    summary="Margins and predicted step response of a gain set (nothing applied)",
)
async def preview_gains(axis: str, body: StepPreviewIn, svc: Svc, who: Viewer) -> dict[str, Any]:
    check_axis(axis)
    current = svc.engine.gains(axis)
    cand = candidate_gains(svc, axis, body.gains)
    shaping = (getattr(svc.engine.config, "shaping", None) or {}).get(axis) if body.shaped else None
    with evaluable(axis, body.gains):
        out = await svc.work.run(
            who, heavy.gain_preview, _model_json(svc, axis), current, cand,
            body.amplitude_deg, body.duration_s, shaping, svc.settings.min_phase_margin_deg,
        )
    return {
        "axis": axis,
        "gains": heavy.result_json(cand),
        **out,
        "min_phase_margin_deg": svc.settings.min_phase_margin_deg,
    }


@router.put(
    "/axes/{axis}/gains", response_model=GainsOut, summary="Apply gains (422 with margins when unsafe)"
)
async def put_gains(axis: str, body: GainsIn, svc: Svc, who: Engineer) -> GainsOut:
    check_axis(axis)
    cand = candidate_gains(svc, axis, body.gains)
    with evaluable(axis, body.gains):
        margins = await margins_of(svc, who, axis, cand)
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
    svc.console.gains_changed(axis, cand)
    await svc.audit.record(who, "gains.set", axis, {"changes": body.gains})
    return await _gains_out(svc, who, axis)


@router.put(
    "/axes/{axis}/model",
    response_model=GainsOut,
    summary="Redesign the axis controller on a workbench model version (422 with the margins or the "
    "model check's figures when refused)",
)
async def put_model(axis: str, body: DesignModelIn, svc: Svc, who: Engineer) -> GainsOut:
    check_axis(axis)
    version = svc.db.get_version(body.version_id)
    if version is None:
        raise NotFound(f"no model version {body.version_id}")
    if version["model"]["axis"] != axis:
        raise Refused(f"version {body.version_id} models the {version['model']['axis']} axis, not {axis}")
    engine = svc.engine
    model = model_from_json(version["model"])
    # The recent motion is copied on the loop; the k-step check (~0.2 s) runs in a worker.
    recent = engine.recent_motion(axis)
    arrays = None if recent is None else (recent.t_s, recent.u_v, recent.theta_rad)
    current = _model_json(svc, axis)
    figures = await svc.work.run(who, heavy.model_check, axis, arrays, version["model"], current)
    check = ModelCheck.from_dict(figures)
    try:
        engine.set_model(axis, model, check=check)
    except ModelRefused as exc:
        raise Refused(str(exc), model_check=figures_deg(exc.figures)) from None
    except ConfigError as exc:
        raise Refused(str(exc), model_check=figures_deg(figures)) from None
    svc.console.model_changed(axis, version["model"], body.version_id)
    await svc.audit.record(who, "model.set", axis, {"version_id": body.version_id,
                                              "effects": version["model"]["effects"]})
    return await _gains_out(svc, who, axis, model_check=figures_deg(figures))


def figures_deg(figures: Mapping[str, object]) -> dict[str, object]:
    """A model check's figures for the client: angles in degrees (``*_rad`` → ``*_deg``)."""
    out: dict[str, object] = {}
    for key, value in figures.items():
        if key.endswith("_rad") and isinstance(value, float):
            out[key[: -len("_rad")] + "_deg"] = math.degrees(value) if math.isfinite(value) else None
        else:
            out[key] = value
    return out


async def _gains_out(
    svc: Service, who: Principal, axis: str, model_check: dict[str, object] | None = None
) -> GainsOut:
    """The axis's current gains, their margins and the configured floor."""
    gains = svc.engine.gains(axis)
    return GainsOut(
        axis=axis,  # type: ignore[arg-type]  # checked by check_axis
        gains=heavy.result_json(gains) | {"type": type(gains).__name__},
        margins=await margins_of(svc, who, axis, gains),
        min_phase_margin_deg=svc.settings.min_phase_margin_deg,
        model_check=model_check,
    )
