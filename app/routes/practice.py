"""The practice rig: a simulated axis hiding one effect picked at random, secret until revealed.

Start one, run experiments on it (each recorded as a workbench measurement), work the loop
(compare, diagnose, add the effect, watch the error fall), run the friction sweep on it as a
friction-ID job, then reveal the truth and set the fitted parameters against it.
"""

from __future__ import annotations

import secrets
from typing import Any

from fastapi import APIRouter

from app import heavy, rig
from app.auth import Engineer, Viewer
from app.db import Database
from app.errors import NotFound
from app.experiments import EXPERIMENTS
from app.modelio import model_from_json, model_to_json, plain
from app.routes.workbench import store_measurement
from app.schemas import ExperimentIn, PracticeNewIn
from app.service import Svc
from tracker.plant.model import AxisModel

router = APIRouter(prefix="/practice", tags=["practice"])
KV_KEY = "practice"


def practice_state(db: Database) -> dict[str, Any] | None:
    return db.get_value(KV_KEY)


def practice_model(db: Database) -> AxisModel | None:
    """The practice rig's true model, or None when no practice rig was started."""
    st = practice_state(db)
    return model_from_json(st["truth"]) if st else None


def public_view(st: dict[str, Any] | None) -> dict[str, Any]:
    """What anyone may see: never the hidden effect until revealed."""
    if st is None:
        return {"active": False}
    out = {
        "active": True,
        "axis": st["axis"],
        "revealed": st["revealed"],
        "measurements": st["measurements"],
        "experiments": list(EXPERIMENTS),
    }
    if st["revealed"]:
        out["truth"] = {"effects": st["truth"]["effects"], "params": st["truth"]["params"]}
    return out


@router.get("", summary="The practice rig (its hidden effect stays secret until revealed)")
async def get_practice(svc: Svc, who: Viewer) -> dict[str, Any]:
    return public_view(practice_state(svc.db))


@router.post("", status_code=201, summary="Start a new practice rig with one random hidden effect")
async def new_practice(body: PracticeNewIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    seed = body.seed if body.seed is not None else secrets.randbelow(2**31)
    truth = rig.random_practice_model(body.axis, seed)
    st: dict[str, Any] = {
        "axis": body.axis,
        "seed": seed,
        "truth": model_to_json(truth, body.axis),
        "revealed": False,
        "measurements": [],
    }
    svc.db.put_value(KV_KEY, st)
    await svc.audit.record(who, "practice.start", body.axis)  # not the seed: it would reveal the effect
    return public_view(st)


@router.post(
    "/experiments", status_code=201, summary="Run an experiment on the practice rig; stored as a measurement"
)
async def run_experiment(body: ExperimentIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    st = practice_state(svc.db)
    if st is None:
        raise NotFound("no practice rig yet: start one with POST /api/v1/practice")
    run_no = len(st["measurements"]) + 1
    label = f"practice {st['axis']} #{run_no}: {body.kind} {body.duration_s:g} s"
    seed = st["seed"] + run_no
    run = await svc.work.run(
        who, heavy.practice_run, st["truth"], st["axis"], body.kind, body.duration_s, seed, label
    )
    rec = await store_measurement(svc, who, label, st["axis"], run.pop("csv"), fitted=run)
    st["measurements"].append(rec["id"])
    svc.db.put_value(KV_KEY, st)
    return rec


@router.post("/reveal", summary="Reveal the hidden effect and compare the fitted parameters with the truth")
async def reveal(svc: Svc, who: Engineer) -> dict[str, Any]:
    st = practice_state(svc.db)
    if st is None:
        raise NotFound("no practice rig yet: start one with POST /api/v1/practice")
    st["revealed"] = True
    svc.db.put_value(KV_KEY, st)
    await svc.audit.record(who, "practice.reveal", st["axis"])
    true_params: dict[str, float] = st["truth"]["params"]
    rows = []
    # The model the person worked on last: the most recently made version of any practice run.
    versions = [v for mid in st["measurements"] for v in svc.db.list_versions(mid)]
    best = max(versions, key=lambda v: v["id"]) if versions else None
    fitted: dict[str, float] = best["model"]["params"] if best else {}
    for name, true_v in true_params.items():
        fit_v = fitted.get(name)
        err = None if fit_v is None or true_v == 0 else 100.0 * (fit_v - true_v) / abs(true_v)
        rows.append({"param": name, "true": true_v, "fitted": fit_v, "error_percent": err})
    return plain(
        {
            **public_view(st),
            "compared_version": best["id"] if best else None,
            "compared_effects": best["model"]["effects"] if best else [],
            "params": rows,
        }
    )
