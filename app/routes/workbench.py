"""The model workbench over HTTP: upload measurements, compare, diagnose, fit, add an effect,
and the model versions of each measurement with their fits (the same semantics as
``tracker model ...``). The heavy work (app/heavy.py) runs in the worker processes of
app/work.py, never on the event loop; these routes only read and write the database.

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

from app import heavy, heavy_camera
from app.auth import Engineer, Principal, Viewer
from app.errors import NotFound, TooLarge, check_axis
from app.modelio import load_version, load_version_record, plain
from app.schemas import AddEffectIn, CompareIn, DiagnoseIn, FitIn, RowId
from app.service import Service, Svc
from tracker.errors import ConfigError, DataError
from tracker.plant.effects import BASE_EFFECTS, BUILTIN_EFFECTS, CATALOGUE, OPTIONAL_EFFECTS, get_effect
from tracker.workbench.camera.model import CAMERA_EFFECTS

router = APIRouter(prefix="/workbench", tags=["workbench"])


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
                "builtin": name in BUILTIN_EFFECTS,
                "signature": e.signature,
                "description": e.description,
                "look_alikes": list(e.look_alikes),
                "experiment": e.experiment,
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


@router.post(
    "/measurements",
    status_code=201,
    summary="Upload a measurement log (CSV t,u,theta; or a PTZ camera log t,speed_cmd,theta)",
)
async def upload(
    svc: Svc,
    who: Engineer,
    file: Annotated[UploadFile, File()],
    axis: Annotated[str, Form(max_length=16)] = "pan",
    name: Annotated[str | None, Form(max_length=200)] = None,
    gain: Annotated[
        float | None, Form(description="amplifier gain K override (N·m/V, or N/V linear)")
    ] = None,
    effects: Annotated[
        str | None, Form(max_length=1000, description="effects to start with, comma separated")
    ] = None,
) -> dict[str, Any]:
    """413 over ``max_upload_bytes`` (before the body is read) or ``max_measurement_rows``."""
    check_axis(axis)
    if gain is not None and not (math.isfinite(gain) and gain > 0):
        raise ConfigError(f"gain must be a positive number (N·m/V, or N/V for a linear axis), got {gain!r}")
    start_effects = tuple(e.strip() for e in (effects or "").split(",") if e.strip())
    for e in start_effects:
        get_effect(e)
    raw = await file.read()  # the request guard has capped the body at max_upload_bytes
    label = (name or file.filename or "upload.csv")[:120]
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"{label}: byte {exc.start} is not UTF-8 text; expected a CSV log") from None
    return await store_measurement(svc, who, label, axis, text, gain, start_effects)


def check_rows(label: str, text: str, max_rows: int) -> None:
    """TooLarge (413) naming the cap when ``text`` has more than ``max_rows`` data rows."""
    rows = text.count("\n") + (not text.endswith("\n")) - 1  # lines less the header
    if rows > max_rows:
        raise TooLarge(
            f"{label}: {rows} data rows; a measurement may have at most {max_rows} "
            "(setting max_measurement_rows)",
            limit_rows=max_rows,
            setting="max_measurement_rows",
        )


async def store_measurement(
    svc: Service,
    who: Principal,
    label: str,
    axis: str,
    text: str,
    gain_nm_per_v: float | None = None,
    effects: tuple[str, ...] = (),
    fitted: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Validate, then store a measurement and its first version: the axis' base model (plus
    ``effects``, with K overridden by ``gain_nm_per_v``, as ``--effects``/``--gain`` on the
    command line) with its parameters fitted (``fitted``: already done by the caller's worker).
    Invalid text or options raise DataError or ConfigError before anything is written."""
    check_rows(label, text, svc.settings.max_measurement_rows)
    if heavy_camera.is_camera(text):
        return await _store_camera_log(svc, who, label, axis, text, gain_nm_per_v, effects)
    if fitted is None:
        fitted = await svc.work.run(who, heavy.first_version, label, axis, text, gain_nm_per_v, effects)
    mid, vid = await asyncio.to_thread(_insert_measurement, svc, label, axis, text, fitted)
    rec = svc.db.get_measurement(mid)
    assert rec is not None
    rec.pop("csv")
    return {**rec, "first_version_id": vid}


async def _store_camera_log(
    svc: Service,
    who: Principal,
    label: str,
    axis: str,
    text: str,
    gain_nm_per_v: float | None,
    effects: tuple[str, ...],
) -> dict[str, Any]:
    """Store a PTZ camera log and its first version, the base camera model with its speed per
    step fitted (app/heavy_camera.py)."""
    if gain_nm_per_v is not None or effects:
        raise ConfigError(f"{label}: a camera log (speed_cmd) takes no gain or starting effects")
    fitted = await svc.work.run(who, heavy_camera.first_version, label, text)
    mid, vid = await asyncio.to_thread(_insert_measurement, svc, label, axis, text, fitted)
    rec = svc.db.get_measurement_meta(mid)
    assert rec is not None
    return {**rec, "kind": heavy_camera.KIND, "first_version_id": vid, "fit": fitted["fit"]}


def _insert_measurement(
    svc: Service, label: str, axis: str, text: str, fitted: dict[str, Any]
) -> tuple[int, int]:
    mid = svc.db.add_measurement(label, axis, text, fitted["n"], fitted["dt_s"])
    return mid, svc.db.add_version(mid, None, "base", fitted["model"], fitted["fit"])


async def stored_measurement(svc: Service, mid: int) -> dict[str, Any]:
    """The stored record (with its CSV text, read in a thread: megabytes); NotFound (404) when unknown."""
    rec = await asyncio.to_thread(svc.db.get_measurement, mid)
    if rec is None:
        raise NotFound(f"no measurement {mid}")
    return rec


@router.get("/measurements", summary="Stored measurements")
async def list_measurements(svc: Svc, who: Viewer) -> list[dict[str, Any]]:
    return svc.db.list_measurements()


@router.get("/measurements/{mid}", summary="A measurement: metadata and decimated series for plots")
async def get_measurement(mid: RowId, svc: Svc, who: Viewer) -> dict[str, Any]:
    rec = await stored_measurement(svc, mid)
    text = rec.pop("csv")
    if heavy_camera.is_camera(text):
        series = await svc.work.run(who, heavy_camera.series, text, rec["name"])
        return {**rec, "kind": heavy_camera.KIND, "series": series}
    series = await svc.work.run(who, heavy.measurement_series, text, rec["name"])
    return {**rec, "kind": "dc", "series": series}


@router.delete("/measurements/{mid}", status_code=204, summary="Delete a measurement and its versions")
async def delete_measurement(mid: RowId, svc: Svc, who: Engineer) -> None:
    if not svc.db.delete_measurement(mid):
        raise NotFound(f"no measurement {mid}")


def _with_version(out: dict[str, Any], v: dict[str, Any]) -> dict[str, Any]:
    return {**out, "version_id": v["id"], "version_label": v["label"]}


@router.post("/measurements/{mid}/compare", summary="Compare a model version with the measurement")
async def compare(mid: RowId, body: CompareIn, svc: Svc, who: Viewer) -> dict[str, Any]:
    rec = await stored_measurement(svc, mid)
    if heavy_camera.is_camera(rec["csv"]):
        cv = _camera_version(svc, mid, body.version_id)
        model_json = None if cv is None else cv["model"]
        out = await svc.work.run(
            who, heavy_camera.compare, rec["csv"], rec["name"], model_json, body.horizon_s
        )
        return out if cv is None else _with_version(out, cv)
    v, _ = load_version(svc.db, mid, body.version_id)
    out = await svc.work.run(
        who, heavy.compare, rec["csv"], rec["name"], v["model"], body.horizon_s, body.mode
    )
    return _with_version(out, v)


@router.post("/measurements/{mid}/diagnose", summary="Rank the missing effects of a model version")
async def diagnose_route(mid: RowId, body: DiagnoseIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    rec = await stored_measurement(svc, mid)
    if heavy_camera.is_camera(rec["csv"]):
        cv = _camera_version(svc, mid, body.version_id)
        model_json = None if cv is None else cv["model"]
        out = await svc.work.run(who, heavy_camera.diagnose, rec["csv"], rec["name"], model_json)
        return out if cv is None else _with_version(out, cv)
    v, _ = load_version(svc.db, mid, body.version_id)
    out = await svc.work.run(who, heavy.diagnose, rec["csv"], rec["name"], v["model"])
    return _with_version(out, v)


async def _refit_into_version(
    svc: Service,
    who: Principal,
    mid: int,
    version_id: int | None,
    free: list[str] | None = None,
    add_effect: str | None = None,
) -> dict[str, Any]:
    rec = await stored_measurement(svc, mid)
    if heavy_camera.is_camera(rec["csv"]):
        return await _refit_camera(svc, who, rec, version_id, free, add_effect)
    v, model = load_version(svc.db, mid, version_id)
    if add_effect is not None:
        get_effect(add_effect)
        if model.has(add_effect):
            raise ConfigError(f"version {v['id']} already has {add_effect!r}")
        label = f"+{add_effect}"
    else:
        label = "refit" if not model.effects else f"refit ({', '.join(model.effects)})"
    earlier = _lineage(svc.db.list_versions(mid), v)
    new = await svc.work.run(
        who, heavy.refit, rec["csv"], rec["name"], rec["axis"], v["model"], free, add_effect, label, earlier
    )
    vid = svc.db.add_version(mid, v["id"], label, new["model"], new["fit"])
    out = svc.db.get_version(vid)
    assert out is not None
    return out


def _camera_version(svc: Service, mid: int, version_id: int | None) -> dict[str, Any] | None:
    """The camera log's version (the latest when ``version_id`` is None); None for a camera log
    stored before camera versions existed (its model is the base one)."""
    if version_id is None and not svc.db.list_versions(mid):
        return None
    return load_version_record(svc.db, mid, version_id)


async def _refit_camera(
    svc: Service,
    who: Principal,
    rec: dict[str, Any],
    version_id: int | None,
    free: list[str] | None,
    add_effect: str | None,
) -> dict[str, Any]:
    """Fit or add-effect on a camera log: a new version of its camera model."""
    mid = int(rec["id"])
    v = _camera_version(svc, mid, version_id)
    if v is None:  # a camera log stored before camera versions: its base version first
        first = await svc.work.run(who, heavy_camera.first_version, rec["name"], rec["csv"])
        v = svc.db.get_version(svc.db.add_version(mid, None, "base", first["model"], first["fit"]))
        assert v is not None
    effects = list(v["model"].get("effects") or [])
    if add_effect is not None:
        if add_effect not in CAMERA_EFFECTS:
            raise ConfigError(
                f"unknown camera effect {add_effect!r}; camera effects are {', '.join(CAMERA_EFFECTS)}"
            )
        if add_effect in effects:
            raise ConfigError(f"version {v['id']} already has {add_effect!r}")
        label = f"+{add_effect}"
    else:
        label = "refit" if not effects else f"refit ({', '.join(effects)})"
    new = await svc.work.run(who, heavy_camera.refit, rec["csv"], rec["name"], v["model"], free, add_effect)
    vid = svc.db.add_version(mid, v["id"], label, new["model"], new["fit"])
    out = svc.db.get_version(vid)
    assert out is not None
    return out


def _lineage(versions: list[dict[str, Any]], v: dict[str, Any]) -> list[tuple[str, float]]:
    """(label, RMS the error budget splits) of ``v`` and its ancestors, oldest first: what the
    new version's error budget counts as explained by each change."""
    by_id = {x["id"]: x for x in versions}
    chain: list[dict[str, Any]] = []
    cur: dict[str, Any] | None = v
    while cur is not None and len(chain) < len(versions):
        chain.append(cur)
        cur = by_id.get(cur["parent_id"])
    out = []
    for x in reversed(chain):
        budget = x["fit"].get("budget") or {}
        rms = budget.get("rms_deg", x["fit"].get("rms_deg"))
        out.append((str(x["label"]), float(rms) if rms is not None else math.nan))
    return out


@router.post(
    "/measurements/{mid}/fit", status_code=201, summary="Refit a version's parameters into a new version"
)
async def fit(mid: RowId, body: FitIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    return await _refit_into_version(svc, who, mid, body.version_id, free=body.free)


@router.post(
    "/measurements/{mid}/add-effect",
    status_code=201,
    summary="Add an effect to a version and refit every parameter (K fixed) into a new version",
)
async def add_effect(mid: RowId, body: AddEffectIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    return await _refit_into_version(svc, who, mid, body.version_id, add_effect=body.effect)


@router.get("/measurements/{mid}/versions", summary="Model versions of a measurement with their fits")
async def versions(mid: RowId, svc: Svc, who: Viewer) -> list[dict[str, Any]]:
    if svc.db.get_measurement_meta(mid) is None:
        raise NotFound(f"no measurement {mid}")
    return svc.db.list_versions(mid)


@router.get("/versions/{vid}", summary="One model version")
async def version(vid: RowId, svc: Svc, who: Viewer) -> dict[str, Any]:
    v = svc.db.get_version(vid)
    if v is None:
        raise NotFound(f"no version {vid}")
    return v
