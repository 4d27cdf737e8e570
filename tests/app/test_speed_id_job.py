"""POST /api/v1/jobs/speed-id: the speed-table identification on the service's PTZ camera, against
the camera emulator over real UDP sockets (its twin's pan table departs from the profile file's:
the job must find it), refused with 409 while tracking is on and on a service without a camera."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import load_settings
from tracker.drivers.camera_profiles import get_profile
from tracker.drivers.camera_twin import CameraTwin

from .conftest import Rig, free_port, poll
from .test_camera_driver import EmulatorThread

API = "/api/v1"
SLOWER = {14: 0.9}  # the hidden camera: step 14 is 10 % slower than the profile file says


def test_speed_id_measures_the_cameras_table(tmp_path: Path) -> None:
    prof = get_profile("generic")
    pan = tuple(v * SLOWER.get(i + 1, 1.0) for i, v in enumerate(prof.speeds_rad_s["pan"]))
    true = dict(enumerate(pan, 1))
    hidden = dataclasses.replace(prof, speeds_rad_s={**prof.speeds_rad_s, "pan": pan})
    camera = EmulatorThread(latency_s=0.02, seed=7, twin=CameraTwin(hidden))
    try:
        settings = load_settings(None, data_dir=str(tmp_path), viewer_enabled=False, viewer_port=free_port(),
                                 audio_enabled=False, driver=f"visca+udp://127.0.0.1:{camera.port}")
        with TestClient(create_app(settings)) as client:
            h = {"X-API-Key": (tmp_path / "admin.key").read_text().strip()}
            status = lambda: client.get(f"{API}/status", headers=h).json()  # noqa: E731
            assert poll(lambda: (st := status())["driver"]["state"] == "connected" and st["mode"] == "hold",
                        5.0), status()

            # tracking on: refused, naming why
            assert client.put(f"{API}/tracking", headers=h, json={"enabled": True}).status_code == 200
            r = client.post(f"{API}/jobs/speed-id", headers=h, json={"axis": "pan", "steps": [14]})
            assert r.status_code == 409 and "tracking is on" in r.json()["detail"], r.text
            assert client.put(f"{API}/tracking", headers=h, json={"enabled": False}).status_code == 200

            r = client.post(f"{API}/jobs/speed-id", headers=h, json={"axis": "pan", "steps": [0, 14]})
            assert r.status_code == 422 and "outside the generic profile's pan table 1..24" in r.text, r.text

            start_deg = status()["pan_deg"]
            r = client.post(f"{API}/jobs/speed-id", headers=h, json={"axis": "pan", "steps": [14, 20]})
            assert r.status_code == 202, r.text
            job_id = r.json()["id"]
            assert poll(lambda: status()["driver"]["held_by"] == "the speed-id job", 2.0), status()
            again = client.post(f"{API}/jobs/speed-id", headers=h, json={"axis": "pan", "steps": [3]})
            assert again.status_code == 409 and "already taken over" in again.text, again.text
            r = client.put(f"{API}/tracking", headers=h, json={"enabled": True})
            assert r.status_code == 409 and "taken over by the speed-id job" in r.text, r.text

            def finished() -> dict | None:  # type: ignore[type-arg]
                j: dict = client.get(f"{API}/jobs/{job_id}", headers=h).json()  # type: ignore[type-arg]
                return j if j["state"] in {"done", "failed", "cancelled"} else None

            mid = poll(lambda: (j := client.get(f"{API}/jobs/{job_id}", headers=h).json())["progress"] > 0
                       and j, 30.0, 0.05)
            assert mid and "of the steps measured" in mid["message"], mid
            job = poll(finished, 60.0, 0.1)
            assert job and job["state"] == "done", job
            res = job["result"]
            measured = {(r["step"], r["direction"]): r for r in res["runs"]}
            assert set(measured) == {(14, 1), (14, -1), (20, 1), (20, -1)}
            for (step, _), run in measured.items():
                assert run["rate_rad_s"] == pytest.approx(true[step], rel=0.03)
            assert measured[(14, 1)]["deviation_percent"] == pytest.approx(-10.0, abs=2.5)
            assert abs(measured[(20, -1)]["deviation_percent"]) < 2.5
            assert res["driver"] == settings.driver and res["profile"] == "generic"
            assert "step 14" in res["notes"][-1]
            # handed back: the engine steers again, and the head is back where it was held
            assert poll(lambda: status()["driver"]["held_by"] is None, 2.0)
            assert poll(lambda: abs(camera.pan_deg() - start_deg) < 0.3, 5.0), (camera.pan_deg(), start_deg)

            # cancelled (between runs): stopped and handed back
            r = client.post(f"{API}/jobs/speed-id", headers=h, json={"axis": "tilt", "steps": [1, 2]})
            assert r.status_code == 202, r.text
            job_id = r.json()["id"]
            assert poll(lambda: status()["driver"]["held_by"] is not None, 2.0)
            assert client.post(f"{API}/jobs/{job_id}/cancel", headers=h).status_code == 200
            job = poll(finished, 30.0, 0.1)
            assert job and job["state"] == "cancelled", job
            assert poll(lambda: status()["driver"]["held_by"] is None, 2.0)
    finally:
        camera.close()


def test_speed_id_needs_a_camera_and_an_engineer(rig: Rig) -> None:
    r = rig.client.post(f"{API}/jobs/speed-id", headers=rig.h("viewer"), json={})
    assert r.status_code == 403
    r = rig.client.post(f"{API}/jobs/speed-id", headers=rig.h("engineer"), json={})
    assert r.status_code == 409, r.text
    assert "needs a PTZ camera driver" in r.json()["detail"] and "'sim'" in r.json()["detail"]
