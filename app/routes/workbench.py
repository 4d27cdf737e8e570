"""The model workbench over HTTP: upload measurements, compare, diagnose, fit, add an effect,
and the model versions of each measurement with their fits (the same semantics as
``tracker model ...``). Heavy work runs in a worker thread, never on the event loop.

Every measurement starts with version 1, the base model of its axis fitted to it. ``fit`` refits the
latest version's parameters into a new version; ``add-effect`` adds an effect and refits all
parameters (K stays fixed) into a new version. Each version keeps its compare figures, so the
history shows the error falling as effects are added.
"""

from __future__ import annotations

import asyncio
import math
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, UploadFile

from app.auth import Engineer, Viewer
from app.db import Database
from app.errors import check_axis
from app.modelio import decimate_index, load_measurement, load_version, model_to_json, plain, series_deg
from app.schemas import AddEffectIn, CompareIn, DiagnoseIn, FitIn
from app.service import Svc
from tracker.errors import ConfigError, DataError
from tracker.plant.effects import BASE_EFFECTS, CATALOGUE, OPTIONAL_EFFECTS, get_effect
from tracker.plant.model import AxisModel
from tracker.workbench.compare import compare_model
from tracker.workbench.data import Measurement, parse_log

router = APIRouter(prefix="/workbench", tags=["workbench"])


def _fit_summary(meas: Measurement, model: AxisModel, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The figures a version keeps: compare fit, RMS error, and the fitter's output when given."""
    cmp = compare_model(meas, model)
    out = {
        "fit_percent": cmp.fit_percent,
        "fit_percent_increment": cmp.fit_percent_increment,
        "rms_deg": cmp.rms_deg,
        "horizon_s": cmp.horizon_s,
    }
    out.update(extra or {})
    return plain(out)


def _add_version(
    db: Database,
    mid: int,
    parent: int | None,
    label: str,
    model: AxisModel,
    axis: str,
    meas: Measurement,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    vid = db.add_version(mid, parent, label, model_to_json(model, axis), _fit_summary(meas, model, extra))
    v = db.get_version(vid)
    assert v is not None
    return v


@router.get("/effects", summary="The effects catalogue: names, kinds, parameters with units and bounds")
async def effects(who: Viewer) -> list[dict[str, Any]]:
    out = []
    for name, e in CATALOGUE.items():
        out.append(
            {
                "name": name,
                "kind": e.kind,
                "base": name in BASE_EFFECTS,
                "optional": name in OPTIONAL_EFFECTS,
                "signature": e.signature,
                "params": [
                    {
                        "name": f"{name}.{p.name}",
                        "unit": p.unit,
                        "default": p.default,
                        "lower": p.lower,
                        "upper": p.upper,
                        "fit": p.fit,
                    }
                    for p in e.params
                ],
            }
        )
    return plain(out)


@router.post("/measurements", status_code=201, summary="Upload a measurement log (CSV t,u,theta)")
async def upload(
    svc: Svc,
    who: Engineer,
    file: Annotated[UploadFile, File()],
    axis: Annotated[str, Form()] = "pan",
    name: Annotated[str | None, Form()] = None,
    gain: Annotated[
        float | None, Form(description="amplifier gain K override (N·m/V, or N/V linear)")
    ] = None,
    effects: Annotated[str | None, Form(description="effects to start with, comma separated")] = None,
) -> dict[str, Any]:
    check_axis(axis)
    if gain is not None and not (math.isfinite(gain) and gain > 0):
        raise ConfigError(f"gain must be a positive number (N·m/V, or N/V for a linear axis), got {gain!r}")
    start_effects = tuple(e.strip() for e in (effects or "").split(",") if e.strip())
    for e in start_effects:
        get_effect(e)
    limit = svc.settings.max_upload_bytes
    raw = await file.read(limit + 1)
    if len(raw) > limit:
        raise DataError(f"{file.filename}: larger than {limit} bytes")
    label = (name or file.filename or "upload.csv")[:120]
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"{label}: byte {exc.start} is not UTF-8 text; expected a CSV log") from None
    return await asyncio.to_thread(store_measurement, svc.db, label, axis, text, gain, start_effects)


def store_measurement(
    db: Database,
    label: str,
    axis: str,
    text: str,
    gain_nm_per_v: float | None = None,
    effects: tuple[str, ...] = (),
) -> dict[str, Any]:
    """Validate, then store a measurement and its first version: the axis' base model (plus
    ``effects``, with K overridden by ``gain_nm_per_v``, as ``--effects``/``--gain`` on the
    command line) with its parameters fitted. Invalid text or options raise DataError or
    ConfigError before anything is written."""
    from tracker.workbench.fit import fit_model

    model = AxisModel.for_axis(axis, effects, gain_nm_per_v=gain_nm_per_v)
    meas = parse_log(text, label)
    res = fit_model(meas, model)
    summary = _fit_summary(meas, res.model, _fitter_extra(res))
    mid = db.add_measurement(label, axis, text, meas.n, meas.dt_s)
    vid = db.add_version(mid, None, "base", model_to_json(res.model, axis), summary)
    rec = db.get_measurement(mid)
    assert rec is not None
    rec.pop("csv")
    return {**rec, "first_version_id": vid}


@router.get("/measurements", summary="Stored measurements")
async def list_measurements(svc: Svc, who: Viewer) -> list[dict[str, Any]]:
    return svc.db.list_measurements()


@router.get("/measurements/{mid}", summary="A measurement: metadata and decimated series for plots")
async def get_measurement(mid: int, svc: Svc, who: Viewer) -> dict[str, Any]:
    rec, meas = await asyncio.to_thread(load_measurement, svc.db, mid)
    rec.pop("csv")
    data: dict[str, Any] = series_deg(meas.t_s, theta=meas.theta_rad)
    data["u_v"] = meas.u_v[decimate_index(meas.n)].round(5).tolist()
    return {**rec, "series": data}


@router.delete("/measurements/{mid}", status_code=204, summary="Delete a measurement and its versions")
async def delete_measurement(mid: int, svc: Svc, who: Engineer) -> None:
    load_measurement(svc.db, mid)
    svc.db.delete_measurement(mid)


def run_compare(db: Database, mid: int, body: CompareIn) -> dict[str, Any]:
    _, meas = load_measurement(db, mid)
    v, model = load_version(db, mid, body.version_id)
    cmp = compare_model(meas, model, horizon_s=body.horizon_s, mode=body.mode)
    out = cmp.to_dict(arrays=False)
    ra = cmp.residuals.to_dict(arrays=True)
    out["residual_analysis"] = ra
    out["series"] = series_deg(
        cmp.t_s, measured=cmp.theta_meas_rad, model=cmp.theta_pred_rad, residual=cmp.residual_rad
    )
    out["version_id"] = v["id"]
    out["version_label"] = v["label"]
    return plain(out)


@router.post("/measurements/{mid}/compare", summary="Compare a model version with the measurement")
async def compare(mid: int, body: CompareIn, svc: Svc, who: Viewer) -> dict[str, Any]:
    return await asyncio.to_thread(run_compare, svc.db, mid, body)


def run_diagnose(db: Database, mid: int, version_id: int | None) -> dict[str, Any]:
    from tracker.workbench.diagnose import diagnose

    _, meas = load_measurement(db, mid)
    v, model = load_version(db, mid, version_id)
    out = plain(diagnose(meas, model).to_dict())
    out["version_id"] = v["id"]
    out["version_label"] = v["label"]
    return out


@router.post("/measurements/{mid}/diagnose", summary="Rank the missing effects of a model version")
async def diagnose_route(mid: int, body: DiagnoseIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    return await asyncio.to_thread(run_diagnose, svc.db, mid, body.version_id)


def _fit_into_version(
    db: Database,
    mid: int,
    parent: dict[str, Any],
    model: AxisModel,
    label: str,
    free: list[str] | None = None,
) -> dict[str, Any]:
    from tracker.workbench.fit import fit_model

    rec, meas = load_measurement(db, mid)
    res = fit_model(meas, model, free=free) if free else fit_model(meas, model)
    return _add_version(db, mid, parent["id"], label, res.model, rec["axis"], meas, _fitter_extra(res))


def _fitter_extra(res: Any) -> dict[str, Any]:
    """What a version keeps from the fitter: parameters with standard errors, convergence."""
    return {
        "params": dict(res.params),
        "stderr": dict(res.stderr),
        "converged": bool(res.converged),
        "free": list(res.free),
    }


def run_fit(db: Database, mid: int, body: FitIn) -> dict[str, Any]:
    v, model = load_version(db, mid, body.version_id)
    label = "refit" if not model.effects else f"refit ({', '.join(model.effects)})"
    return _fit_into_version(db, mid, v, model, label, body.free)


@router.post(
    "/measurements/{mid}/fit", status_code=201, summary="Refit a version's parameters into a new version"
)
async def fit(mid: int, body: FitIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    return await asyncio.to_thread(run_fit, svc.db, mid, body)


def run_add_effect(db: Database, mid: int, body: AddEffectIn) -> dict[str, Any]:
    get_effect(body.effect)
    v, model = load_version(db, mid, body.version_id)
    if model.has(body.effect):
        raise ConfigError(f"version {v['id']} already has {body.effect!r}")
    return _fit_into_version(db, mid, v, model.with_effect(body.effect), f"+{body.effect}")


@router.post(
    "/measurements/{mid}/add-effect",
    status_code=201,
    summary="Add an effect to a version and refit every parameter (K fixed) into a new version",
)
async def add_effect(mid: int, body: AddEffectIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    return await asyncio.to_thread(run_add_effect, svc.db, mid, body)


@router.get("/measurements/{mid}/versions", summary="Model versions of a measurement with their fits")
async def versions(mid: int, svc: Svc, who: Viewer) -> list[dict[str, Any]]:
    load_measurement(svc.db, mid)
    return svc.db.list_versions(mid)


@router.get("/versions/{vid}", summary="One model version")
async def version(vid: int, svc: Svc, who: Viewer) -> dict[str, Any]:
    from app.errors import NotFound

    v = svc.db.get_version(vid)
    if v is None:
        raise NotFound(f"no version {vid}")
    return v
