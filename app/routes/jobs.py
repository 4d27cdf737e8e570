"""Jobs: friction-ID and, on a PTZ camera, the speed-table identification (start, progress,
cancel, result; :mod:`app.speed_id_job`) and the list of recent jobs.

Friction-ID runs the seed's experiment automated — constant voltages across the range, the
steady speed of each — through ``tracker.workbench.experiments.friction_id`` on a simulated rig built like
the live one (``source="rig"``) or like the practice rig (``source="practice"``), in a worker
process, so the live camera keeps tracking, on time, while the job runs; or on the service's own
DC rig (``source="live"``, a serial motor controller), which the job takes over while it runs
(:mod:`app.friction_live_job`).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from app.auth import Engineer, Principal, Viewer
from app.errors import NotFound
from app.friction_live_job import KIND as LIVE_KIND
from app.friction_live_job import check_rig, friction_live_job
from app.modelio import model_to_json
from app.routes.practice import practice_model, practice_state
from app.schemas import FrictionJobIn, RowId, SpeedIdJobIn
from app.service import Svc
from app.speed_id_job import KIND, check_camera, speed_id_job
from app.worker_tasks import friction_job

router = APIRouter(prefix="/jobs", tags=["jobs"])


@router.post("/friction-id", status_code=202, summary="Start a friction-ID job; poll GET /jobs/{id}")
async def start_friction_id(body: FrictionJobIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    """source "live": 409 when the driver is not a serial rig, tracking is on, or the rig is not
    free to move (app/friction_live_job.py)."""
    if body.source == "live":
        rig = check_rig(svc.engine, svc.settings.driver)
        job = friction_live_job(rig, body.axis, body.voltages)
        return await _started(svc, who, LIVE_KIND, body.model_dump(),
                              svc.jobs.start_local(LIVE_KIND, body.model_dump(), job))
    hidden = practice_model(svc.db) if body.source == "practice" else None
    if body.source == "practice" and hidden is None:
        raise NotFound("no practice rig yet: start one with POST /api/v1/practice")
    hidden_axis = (practice_state(svc.db) or {}).get("axis", body.axis)
    rig_config = None if svc.settings.rig_config is None else str(svc.settings.rig_config)
    hidden_json = None if hidden is None else model_to_json(hidden, hidden_axis)
    job_id = svc.jobs.start("friction-id", body.model_dump(), friction_job, rig_config, hidden_json,
                            hidden_axis, body.axis, body.voltages)
    return await _started(svc, who, "friction-id", body.model_dump(), job_id)


@router.post("/speed-id", status_code=202,
             summary="Start a speed-table identification on the PTZ camera; poll GET /jobs/{id}")
async def start_speed_id(body: SpeedIdJobIn, svc: Svc, who: Engineer) -> dict[str, Any]:
    """409 when the driver is not a camera, tracking is on, or the camera is not free to move."""
    cam = check_camera(svc.engine, svc.settings.driver)
    steps = None if body.steps is None else tuple(body.steps)
    job_id = svc.jobs.start_local(KIND, body.model_dump(), speed_id_job(cam, body.axis, steps, body.count))
    return await _started(svc, who, KIND, body.model_dump(), job_id)


async def _started(
    svc: Svc, who: Principal, kind: str, params: dict[str, Any], job_id: int
) -> dict[str, Any]:
    """The audit line for a started job, and the job as the store has it."""
    await svc.audit.record(who, "job.start", str(job_id), {"kind": kind, **params})
    return svc.db.get_job(job_id) or {"id": job_id}


@router.get("", summary="Recent jobs (newest first, without results)")
async def list_jobs(svc: Svc, who: Viewer) -> list[dict[str, Any]]:
    return svc.db.list_jobs()


@router.get("/{job_id}", summary="A job: state, progress, message and (when done) its result")
async def get_job(job_id: RowId, svc: Svc, who: Viewer) -> dict[str, Any]:
    job = svc.db.get_job(job_id)
    if job is None:
        raise NotFound(f"no job {job_id}")
    return job


@router.post("/{job_id}/cancel", summary="Ask a running job to stop")
async def cancel_job(job_id: RowId, svc: Svc, who: Engineer) -> dict[str, Any]:
    job = svc.jobs.cancel(job_id)
    await svc.audit.record(who, "job.cancel", str(job_id))
    return job
