"""Friction-ID jobs over HTTP: start, progress, result (recovers the rig's friction), cancel."""

from __future__ import annotations

import pytest

from tracker.plant.params import get_preset

from .conftest import Rig, poll

API = "/api/v1/jobs"


def wait_done(rig: Rig, job_id: int) -> dict:  # type: ignore[type-arg]
    def finished() -> dict | None:  # type: ignore[type-arg]
        j = rig.client.get(f"{API}/{job_id}", headers=rig.h("viewer")).json()
        return j if j["state"] in {"done", "failed", "cancelled"} else None

    job = poll(finished, 120.0, 0.1)  # ~5 s on a quiet machine; a busy CI box is slower
    assert job, "job did not finish in 120 s"
    return job


def test_friction_id_recovers_the_rig_friction(rig: Rig) -> None:
    r = rig.client.post(f"{API}/friction-id", headers=rig.h("engineer"), json={"axis": "pan"})
    assert r.status_code == 202, r.text
    job = wait_done(rig, r.json()["id"])
    assert job["state"] == "done", job["message"]
    assert job["progress"] == pytest.approx(1.0)
    res = job["result"]
    seed = get_preset("pan").base_params()
    assert res["params"]["coulomb.torque"] == pytest.approx(seed["coulomb.torque"], rel=0.05)
    assert res["params"]["viscous.b"] == pytest.approx(seed["viscous.b"], rel=0.10)
    assert len(res["plot"]["velocity_rad_s"]) == len(res["plot"]["torque_nm"]) >= 10
    listed = rig.client.get(API, headers=rig.h("viewer")).json()
    assert listed[0]["id"] == job["id"] and "result" not in listed[0]


def test_friction_id_can_be_cancelled(rig: Rig) -> None:
    r = rig.client.post(f"{API}/friction-id", headers=rig.h("engineer"), json={"axis": "tilt"})
    job_id = r.json()["id"]
    assert rig.client.post(f"{API}/{job_id}/cancel", headers=rig.h("engineer")).status_code == 200
    job = wait_done(rig, job_id)
    assert job["state"] == "cancelled" and job["result"] is None


def test_unknown_job_is_404(rig: Rig) -> None:
    assert rig.client.get(f"{API}/987654", headers=rig.h("viewer")).status_code == 404
    assert rig.client.post(f"{API}/987654/cancel", headers=rig.h("engineer")).status_code == 404


def test_bad_axis_is_422(rig: Rig) -> None:
    assert (
        rig.client.post(f"{API}/friction-id", headers=rig.h("engineer"), json={"axis": "roll"}).status_code
        == 422
    )
