"""Gains: read with margins, preview with a predicted step response, refuse unsafe sets with 422."""

from __future__ import annotations

import pytest

from .conftest import Rig

API = "/api/v1"


def test_get_gains_reports_margins_over_the_floor(rig: Rig) -> None:
    r = rig.client.get(f"{API}/axes/tilt/gains", headers=rig.h("viewer"))
    assert r.status_code == 200
    g = r.json()
    assert g["margins"]["stable"] is True
    assert g["margins"]["phase_margin_deg"] >= g["min_phase_margin_deg"]
    assert g["margins"]["acceptable"] is True


def test_unknown_axis_is_404(rig: Rig) -> None:
    assert rig.client.get(f"{API}/axes/roll/gains", headers=rig.h("viewer")).status_code == 404
    r = rig.client.put(f"{API}/axes/roll/gains", headers=rig.h("engineer"), json={"gains": {}})
    assert r.status_code == 404 and "roll" in r.json()["detail"]


def test_preview_predicts_a_step_that_settles_on_the_target(rig: Rig) -> None:
    r = rig.client.post(
        f"{API}/axes/pan/gains/preview",
        headers=rig.h("viewer"),
        json={"gains": {}, "amplitude_deg": 30, "duration_s": 1.5},
    )
    assert r.status_code == 200, r.text
    step = r.json()["step"]
    assert len(step["t_s"]) == len(step["angle_deg"]) > 50
    assert step["angle_deg"][0] == pytest.approx(0.0, abs=0.5)
    assert step["angle_deg"][-1] == pytest.approx(30.0, abs=0.6)
    assert step["rise_time_s"] is not None and 0 < step["rise_time_s"] < 1.0


def test_unsafe_gains_are_refused_with_margins_and_nothing_changes(rig: Rig) -> None:
    before = rig.client.get(f"{API}/axes/pan/gains", headers=rig.h("viewer")).json()["gains"]
    # The service's default controller has a derivative gain; without one this test would check nothing.
    kd = before.get("kd_v_s_per_rad")
    assert kd is not None, f"controller {before['type']} has no derivative gain"
    # removing most of the damping collapses the phase margin
    r = rig.client.put(
        f"{API}/axes/pan/gains", headers=rig.h("engineer"), json={"gains": {"kd_v_s_per_rad": kd * 0.05}}
    )
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["margins"]["phase_margin_deg"] < body["min_phase_margin_deg"]
    assert "phase margin" in body["detail"]
    after = rig.client.get(f"{API}/axes/pan/gains", headers=rig.h("viewer")).json()["gains"]
    assert after == before


def test_unknown_gain_field_is_422(rig: Rig) -> None:
    r = rig.client.put(f"{API}/axes/pan/gains", headers=rig.h("engineer"), json={"gains": {"warp_factor": 9}})
    assert r.status_code == 422 and "warp_factor" in r.json()["detail"]


def test_a_safe_change_is_applied(rig: Rig) -> None:
    before = rig.client.get(f"{API}/axes/tilt/gains", headers=rig.h("viewer")).json()
    field = "observer_bandwidth_hz"
    assert field in before["gains"], f"controller {before['type']} has no observer bandwidth"
    new = before["gains"][field] * 1.05
    preview = rig.client.post(
        f"{API}/axes/tilt/gains/preview", headers=rig.h("viewer"), json={"gains": {field: new}}
    ).json()
    assert preview["margins"]["acceptable"], preview["margins"]
    r = rig.client.put(f"{API}/axes/tilt/gains", headers=rig.h("engineer"), json={"gains": {field: new}})
    assert r.status_code == 200, r.text
    assert r.json()["gains"][field] == pytest.approx(new)
    rig.client.put(
        f"{API}/axes/tilt/gains", headers=rig.h("engineer"), json={"gains": {field: before["gains"][field]}}
    )


def test_raw_step_shows_less_damping_as_more_overshoot(rig: Rig) -> None:
    kd = rig.client.get(f"{API}/axes/pan/gains", headers=rig.h("viewer")).json()["gains"]["kd_v_s_per_rad"]
    overshoot = []
    for factor in (1.0, 0.5):
        r = rig.client.post(
            f"{API}/axes/pan/gains/preview",
            headers=rig.h("viewer"),
            json={
                "gains": {"kd_v_s_per_rad": kd * factor},
                "amplitude_deg": 5,
                "duration_s": 0.6,
                "shaped": False,
            },
        )
        assert r.status_code == 200, r.text
        overshoot.append(r.json()["step"]["overshoot_percent"])
    assert overshoot[1] > overshoot[0] + 5.0
