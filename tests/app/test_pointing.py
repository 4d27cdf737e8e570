"""Status, tracking, pointing (limits, control lock), jog with auto-stop, presets, the 3D view."""

from __future__ import annotations

import pytest

from .conftest import Rig, poll

API = "/api/v1"


def status(rig: Rig) -> dict:  # type: ignore[type-arg]
    r = rig.client.get(f"{API}/status", headers=rig.h("viewer"))
    assert r.status_code == 200
    return r.json()


def release_all(rig: Rig) -> None:
    rig.client.post(f"{API}/control", headers=rig.h("engineer"), params={"force": True})
    rig.client.delete(f"{API}/pointing", headers=rig.h("engineer"))


def test_status_reports_degrees_mode_and_limits(rig: Rig) -> None:
    s = status(rig)
    assert s["limits_deg"] == {"pan": pytest.approx(90.0), "tilt": pytest.approx(45.0)}
    assert s["mode"] in {"hold", "tracking", "manual", "disabled", "fault"}
    assert isinstance(s["faults"], list)
    t0 = s["t_s"]
    assert poll(lambda: status(rig)["t_s"] > t0 + 0.1, 3.0), "engine time does not advance"


def test_pointing_moves_the_camera_and_the_3d_view_agrees(rig: Rig) -> None:
    release_all(rig)
    r = rig.client.put(f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": 25.0, "tilt_deg": -8.0})
    assert r.status_code == 200, r.text
    assert r.json()["mode"] == "manual"

    def arrived() -> dict | None:  # type: ignore[type-arg]
        s = status(rig)
        ok = abs(s["pan_deg"] - 25.0) < 0.2 and abs(s["tilt_deg"] + 8.0) < 0.2
        return s if ok else None

    s = poll(arrived, 6.0)
    assert s, f"camera did not reach 25/-8: {status(rig)}"
    assert s["control_holder"]["name"] == "test operator"
    view = poll(
        lambda: (
            (v := rig.client.get(f"{API}/viewer", headers=rig.h("viewer")).json())
            and abs(v["pan_deg"] - 25.0) < 0.5
            and v
        ),
        3.0,
    )
    assert view, "3D view did not follow"
    assert abs(view["tilt_deg"] + 8.0) < 0.5
    assert view["share_url_enabled"] is False
    rig.client.delete(f"{API}/pointing", headers=rig.h("operator"))


@pytest.mark.parametrize(
    ("body", "axis", "limit"),
    [({"pan_deg": 120.0, "tilt_deg": 0.0}, "pan", 90.0), ({"pan_deg": 0.0, "tilt_deg": -60.0}, "tilt", 45.0)],
    ids=["pan", "tilt"],
)
def test_out_of_range_is_422_with_the_limit(rig: Rig, body: dict, axis: str, limit: float) -> None:  # type: ignore[type-arg]
    release_all(rig)
    before = status(rig)["pan_target_deg"]
    r = rig.client.put(f"{API}/pointing", headers=rig.h("operator"), json=body)
    assert r.status_code == 422
    j = r.json()
    assert j["axis"] == axis and j["limit_deg"] == pytest.approx(limit)
    assert f"±{limit:g}°" in j["detail"]
    assert status(rig)["pan_target_deg"] == pytest.approx(before, abs=1e-6)
    rig.client.delete(f"{API}/pointing", headers=rig.h("operator"))


@pytest.mark.parametrize(
    "bad",
    [
        '{"pan_deg": "NaN", "tilt_deg": 0}',
        '{"pan_deg": 1}',
        '{"pan_deg": "x", "tilt_deg": 0}',
        '{"pan_deg": 1, "tilt_deg": 0, "extra": 1}',
        "not json",
    ],
    ids=["nan", "missing", "text", "extra", "garbage"],
)
def test_malformed_pointing_is_422(rig: Rig, bad: str) -> None:
    r = rig.client.put(
        f"{API}/pointing", headers={**rig.h("operator"), "Content-Type": "application/json"}, content=bad
    )
    assert r.status_code == 422


def test_one_holder_of_manual_control_others_see_who(rig: Rig) -> None:
    release_all(rig)
    assert (
        rig.client.put(
            f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": 5, "tilt_deg": 0}
        ).status_code
        == 200
    )
    r = rig.client.put(f"{API}/pointing", headers=rig.h("operator2"), json={"pan_deg": -5, "tilt_deg": 0})
    assert r.status_code == 409
    assert r.json()["holder"] == "test operator"
    assert (
        rig.client.put(f"{API}/jog/pan", headers=rig.h("operator2"), json={"rate_deg_s": 5}).status_code
        == 409
    )
    assert (
        rig.client.put(f"{API}/tracking", headers=rig.h("operator2"), json={"enabled": True}).status_code
        == 409
    )
    assert status(rig)["control_holder"]["name"] == "test operator"
    # an engineer may take over
    assert (
        rig.client.post(f"{API}/control", headers=rig.h("engineer"), params={"force": True}).status_code
        == 200
    )
    assert status(rig)["control_holder"]["name"] == "test engineer"
    rig.client.delete(f"{API}/pointing", headers=rig.h("engineer"))
    assert status(rig)["control_holder"] is None


def test_tracking_toggle_and_reenabling_ends_the_override(rig: Rig) -> None:
    release_all(rig)
    assert (
        rig.client.put(
            f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": 3, "tilt_deg": 0}
        ).status_code
        == 200
    )
    r = rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": True})
    assert r.status_code == 200 and r.json()["tracking"] is True
    s = status(rig)
    assert s["tracking"] is True and s["mode"] != "manual" and s["control_holder"] is None
    r = rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": False})
    assert r.json()["tracking"] is False
    assert (
        rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": "maybe"}).status_code
        == 422
    )


def test_jog_moves_then_stops_by_itself(rig: Rig) -> None:
    release_all(rig)
    # a jog starts from where the axis is: bring it to rest at 0° first
    assert (
        rig.client.put(
            f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": 0, "tilt_deg": 0}
        ).status_code
        == 200
    )
    assert poll(lambda: abs(status(rig)["pan_deg"]) < 0.05, 6.0)
    start = status(rig)["pan_target_deg"]
    r = rig.client.put(f"{API}/jog/pan", headers=rig.h("operator"), json={"rate_deg_s": 20.0})
    assert r.status_code == 200 and r.json()["auto_stop_s"] > 0
    moved = poll(lambda: abs(status(rig)["pan_target_deg"] - start) > 2.0, 3.0)
    assert moved, "jog did not move the target"

    # no renewal: the target stops within the auto-stop timeout, then stays
    def settled() -> bool:
        a = status(rig)["pan_target_deg"]
        b = poll(lambda: False, 0.3) or status(rig)["pan_target_deg"]
        return abs(a - b) < 1e-6

    assert poll(settled, 3.0), "jog did not auto-stop"
    stopped_at = status(rig)["pan_target_deg"]
    assert abs(stopped_at - start) < 20.0 * 1.5  # ≤ 0.5 s timeout + request latency at 20°/s
    assert rig.client.delete(f"{API}/jog/pan", headers=rig.h("operator")).status_code == 200
    assert (
        rig.client.put(f"{API}/jog/roll", headers=rig.h("operator"), json={"rate_deg_s": 1}).status_code
        == 404
    )
    rig.client.delete(f"{API}/pointing", headers=rig.h("operator"))


def test_presets_store_list_recall_delete(rig: Rig) -> None:
    release_all(rig)
    h = rig.h("operator")
    assert (
        rig.client.put(
            f"{API}/presets/lectern", headers=h, json={"pan_deg": -12.5, "tilt_deg": 4}
        ).status_code
        == 200
    )
    assert {"name": "lectern", "pan_deg": -12.5, "tilt_deg": 4.0} in rig.client.get(
        f"{API}/presets", headers=rig.h("viewer")
    ).json()
    r = rig.client.post(f"{API}/presets/lectern/recall", headers=h)
    assert r.status_code == 200 and r.json()["pan_target_deg"] == pytest.approx(-12.5)
    assert poll(lambda: abs(status(rig)["pan_deg"] + 12.5) < 0.3, 6.0)
    r = rig.client.put(f"{API}/presets/far", headers=h, json={"pan_deg": 95, "tilt_deg": 0})
    assert r.status_code == 422 and r.json()["limit_deg"] == pytest.approx(90.0)
    assert rig.client.put(f"{API}/presets/bad%2Fname", headers=h, json={}).status_code in (404, 422)
    assert rig.client.post(f"{API}/presets/nowhere/recall", headers=h).status_code == 404
    assert rig.client.delete(f"{API}/presets/lectern", headers=h).status_code == 204
    assert rig.client.delete(f"{API}/presets/lectern", headers=h).status_code == 404
    names = [p["name"] for p in rig.client.get(f"{API}/presets", headers=h).json()]
    assert "far" not in names and "lectern" not in names
    rig.client.delete(f"{API}/pointing", headers=h)


def test_health_needs_no_key(rig: Rig) -> None:
    assert rig.client.get(f"{API}/health").json()["engine_running"] is True


def test_openapi_lists_the_issue_endpoints(rig: Rig) -> None:
    paths = rig.client.get(f"{API}/openapi.json").json()["paths"]
    for p in (
        "/api/v1/status",
        "/api/v1/tracking",
        "/api/v1/pointing",
        "/api/v1/presets",
        "/api/v1/axes/{axis}/gains",
        "/api/v1/workbench/measurements",
    ):
        assert p in paths


def test_every_page_asset_is_served_locally(rig: Rig) -> None:
    import re

    for page in ("/", "/api/docs"):
        html = rig.client.get(page).text
        refs = re.findall(r'(?:src|href)=["\']([^"\']+)["\']', html) + re.findall(
            r'url: ?["\']([^"\']+)', html
        )
        external = [r for r in refs if re.match(r"(https?:)?//", r)]
        assert not external, f"{page} loads {external}"
        for ref in refs:
            if ref.startswith("/static/"):
                assert rig.client.get(ref).status_code == 200, ref


def test_a_latched_fault_shows_and_an_engineer_clears_it(rig: Rig) -> None:
    driver = rig.client.app.state.svc.engine.driver  # type: ignore[attr-defined]
    driver.latch_fault("test: over-travel on pan")
    s = poll(lambda: (st := status(rig))["mode"] == "fault" and st, 3.0)
    assert s and s["faults"] == ["test: over-travel on pan"]
    assert rig.client.post(f"{API}/faults/clear", headers=rig.h("operator")).status_code == 403
    r = rig.client.post(f"{API}/faults/clear", headers=rig.h("engineer"))
    assert r.status_code == 200 and r.json()["faults"] == []
    assert poll(lambda: status(rig)["mode"] != "fault", 3.0)
