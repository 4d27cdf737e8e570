"""The console's workbench on a PTZ camera log (CSV t,speed_cmd,theta) made by the independent
generator: it is stored as a camera log, diagnose names the hidden latency, compare shows the
camera model's fit; a DC log beside it still gets its DC treatment."""

from __future__ import annotations

import random

import pytest

from tests.tracker.workbench.camera.ptz_log_generator import generate, random_truth, to_csv
from tracker.workbench.experiments.experiments import generate_measurement, random_hidden_model
from tracker.workbench.measurements.data import format_log

from .conftest import Rig
from .test_workbench import API, upload


@pytest.fixture(scope="module")
def latency_csv() -> str:
    truth = random_truth(random.Random(7), latency=True)
    assert truth.latency_s > 0.05
    return to_csv(*generate(truth, 45.0, 7))


def test_camera_log_upload_diagnose_and_compare(rig: Rig, latency_csv: str) -> None:
    r = upload(rig, latency_csv, name="ptz.csv")
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["kind"] == "camera" and rec["first_version_id"] is not None
    assert rec["n"] == latency_csv.count("\n") - 1
    listed = {m["id"]: m for m in rig.client.get(f"{API}/measurements", headers=rig.h("viewer")).json()}
    assert listed[rec["id"]]["kind"] == "camera"

    d = rig.client.post(f"{API}/measurements/{rec['id']}/diagnose", json={}, headers=rig.h("engineer"))
    assert d.status_code == 200, d.text
    out = d.json()
    assert out["kind"] == "camera" and out["verdict"] == "latency"
    top = out["candidates"][0]
    assert top["effect"] == "latency" and top["significant"] and top["evidence"]
    assert isinstance(out["fit_percent"], float) and out["rms_deg"] > 0

    c = rig.client.post(
        f"{API}/measurements/{rec['id']}/compare", json={"horizon_s": 0.5}, headers=rig.h("viewer")
    )
    assert c.status_code == 200, c.text
    cmp = c.json()
    assert cmp["kind"] == "camera" and cmp["rms_deg"] > 0 and "steady" in cmp["regimes"]
    assert len(cmp["series"]["t_s"]) == len(cmp["series"]["residual_deg"]) > 0

    m = rig.client.get(f"{API}/measurements/{rec['id']}", headers=rig.h("viewer")).json()
    assert m["kind"] == "camera" and len(m["series"]["speed_cmd"]) == len(m["series"]["t_s"])


def test_camera_log_versions_show_the_error_fall(rig: Rig, latency_csv: str) -> None:
    """The loop on a camera log: the base version misses the hidden latency, the diagnosis names
    it, adding it makes a new version whose fitted latency is the generator's (command + report
    latency) and whose error fell; the new version's diagnosis has nothing left to add."""
    truth = random_truth(random.Random(7), latency=True)
    r = upload(rig, latency_csv, name="ptz-versions.csv")
    mid, v1 = r.json()["id"], r.json()["first_version_id"]
    base = rig.client.get(f"{API}/versions/{v1}", headers=rig.h("viewer")).json()
    assert base["model"]["kind"] == "camera" and base["model"]["effects"] == []
    eng = rig.h("engineer")
    d = rig.client.post(f"{API}/measurements/{mid}/diagnose", json={"version_id": v1}, headers=eng).json()
    assert d["verdict"] == "latency" and d["version_id"] == v1

    a = rig.client.post(f"{API}/measurements/{mid}/add-effect", json={"effect": "latency"}, headers=eng)
    assert a.status_code == 201, a.text
    v2 = a.json()
    assert v2["label"] == "+latency" and v2["parent_id"] == v1 and v2["model"]["effects"] == ["latency"]
    fitted = v2["model"]["params"]["latency.seconds"]
    true = truth.latency_s
    assert abs(fitted - true) < 0.25 * truth.period_s + 0.01, (fitted, true)
    assert v2["fit"]["rms_deg"] < 0.5 * base["fit"]["rms_deg"]

    d2 = rig.client.post(f"{API}/measurements/{mid}/diagnose", json={}, headers=eng).json()
    assert d2["version_id"] == v2["id"] and d2["verdict"] is None, d2["candidates"][:2]
    c = rig.client.post(f"{API}/measurements/{mid}/compare", json={"version_id": v1}, headers=rig.h("viewer"))
    assert c.json()["version_id"] == v1 and c.json()["rms_deg"] > 2 * d2["rms_deg"]
    listed = rig.client.get(f"{API}/measurements/{mid}/versions", headers=rig.h("viewer")).json()
    assert [v["label"] for v in listed] == ["base", "+latency"]

    for bad, why in (("offset", "unknown camera effect"), ("latency", "already has")):
        e = rig.client.post(f"{API}/measurements/{mid}/add-effect", json={"effect": bad}, headers=eng)
        assert e.status_code == 422 and why in e.json()["detail"], e.text
    assert len(rig.client.get(f"{API}/measurements/{mid}/versions", headers=rig.h("viewer")).json()) == 2


def test_bad_camera_log_is_400_naming_the_line(rig: Rig, latency_csv: str) -> None:
    lines = latency_csv.splitlines()
    lines[5] = lines[5].split(",")[0] + ",2.5," + lines[5].split(",")[2]
    r = upload(rig, "\n".join(lines) + "\n", name="bad-ptz.csv")
    assert r.status_code == 400 and "line 6" in r.text and "speed_cmd" in r.text


def test_dc_log_still_gets_a_version(rig: Rig) -> None:
    truth = random_hidden_model("pan", ["offset"], seed=11)
    r = upload(rig, format_log(generate_measurement(truth, duration_s=15.0, seed=5)), name="dc.csv")
    assert r.status_code == 201 and r.json()["first_version_id"] is not None
    listed = {m["id"]: m for m in rig.client.get(f"{API}/measurements", headers=rig.h("viewer")).json()}
    assert listed[r.json()["id"]]["kind"] == "dc"
