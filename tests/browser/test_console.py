"""The console in Chromium: sign in, live angles, tracking, pointing (status and 3D view agree),
the workbench loop with the diagnosis and the falling-error chart."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from tracker.workbench.experiments.experiments import generate_measurement, random_hidden_model
from tracker.workbench.measurements.data import format_log

from .conftest import Server

pytestmark = pytest.mark.browser
T = 30_000  # ms; generous: Chromium renders WebGL in software next to the server on 2 shared cores


def test_wrong_key_is_refused(browser, server: Server) -> None:  # type: ignore[no-untyped-def]
    pg = browser.new_page()
    pg.goto(server.url + "/")
    pg.fill("#key-input", "3dat_nope")
    pg.click("#signin-form button[type=submit]")
    pg.wait_for_function("document.getElementById('signin-error').textContent.length > 0")
    assert "not known" in pg.text_content("#signin-error")
    assert pg.is_hidden("#main")
    pg.close()


def test_angles_move_and_pointing_agrees_with_status_and_3d_view(page, server: Server) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function("window.console3dat_live && window.console3dat_live.frames > 20", timeout=T)
    t0 = page.evaluate("window.console3dat_live.lastFrame.t_s")
    page.wait_for_function(f"window.console3dat_live.lastFrame.t_s > {t0} + 0.5", timeout=T)

    page.fill("#point-pan", "20")
    page.fill("#point-tilt", "6")
    page.click("#point-form button[type=submit]")
    page.wait_for_function(
        "Math.abs(parseFloat(document.getElementById('pan-val').textContent) - 20) < 0.3", timeout=T
    )
    page.wait_for_function(
        "Math.abs(parseFloat(document.getElementById('tilt-val').textContent) - 6) < 0.3", timeout=T
    )
    # the page's own view of the 3D scene (read back from the viser handles) and the status agree
    page.wait_for_function(
        "(() => { const v = window.console3dat_status && window.console3dat_status.viewer;"
        " return v && Math.abs(v.pan_deg - 20) < 0.3 && Math.abs(v.tilt_deg - 6) < 0.3; })()",
        timeout=T,
    )
    shown = page.text_content("#viewer-state")
    assert re.search(r"3D view shows pan (19\.\d|20\.\d)°, tilt (5\.\d|6\.\d)°", shown), shown
    status = server.api("GET", "/status").json()
    assert status["pan_deg"] == pytest.approx(20, abs=0.3) and status["tilt_deg"] == pytest.approx(6, abs=0.3)
    assert status["viewer"]["pan_deg"] == pytest.approx(status["pan_deg"], abs=0.5)
    assert status["viewer"]["share_url_enabled"] is False
    assert page.text_content("#mode") == "manual"
    frame = page.frame_locator("#viewer-box iframe")
    assert frame.locator("body").count() == 1
    # the view comes through the console (same origin, same key), and viser's client in the
    # iframe connects through the relay
    assert page.get_attribute("#viewer-box iframe", "src") == "/api/v1/view/"
    deadline = time.monotonic() + T / 1000
    while server.api("GET", "/viewer").json()["clients"] < 1 and time.monotonic() < deadline:
        time.sleep(0.2)
    assert server.api("GET", "/viewer").json()["clients"] >= 1

    # click-to-point: the left part of the field is positive pan (as seen from behind the camera)
    box = page.locator("#point-field").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.25, box["y"] + box["height"] * 0.5)
    page.wait_for_function("parseFloat(document.getElementById('pan-tgt').textContent) > 30", timeout=T)
    # holding an arrow key jogs (press/release); the target stops moving after the release
    page.wait_for_function(
        "Math.abs(parseFloat(document.getElementById('pan-val').textContent)"
        " - parseFloat(document.getElementById('pan-tgt').textContent)) < 0.5",
        timeout=T,
    )
    before = float(page.text_content("#pan-tgt"))
    page.locator("#pause").focus()
    page.keyboard.down("ArrowLeft")
    page.wait_for_function(
        f"parseFloat(document.getElementById('pan-tgt').textContent) > {before} + 3", timeout=T
    )
    page.keyboard.up("ArrowLeft")
    page.wait_for_timeout(1000)  # release plus the engine's auto-stop window
    held = float(page.text_content("#pan-tgt"))
    page.wait_for_timeout(500)
    assert float(page.text_content("#pan-tgt")) == pytest.approx(held, abs=0.05)
    page.click("#release")


def test_tracking_toggle(page, server: Server) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function("window.console3dat_status !== undefined", timeout=T)
    before = server.api("GET", "/status").json()["tracking"]
    assert page.is_checked("#tracking-toggle") is before
    page.click(".switch .slider")
    page.wait_for_function(
        f"window.console3dat_status && window.console3dat_status.tracking === {str(not before).lower()}",
        timeout=T,
    )
    assert server.api("GET", "/status").json()["tracking"] is (not before)
    page.click(".switch .slider")
    page.wait_for_function(f"window.console3dat_status.tracking === {str(before).lower()}", timeout=T)


def test_upload_diagnose_add_effect_and_the_error_falls(page, server: Server, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    csv = tmp_path / "gravity_run.csv"
    csv.write_text(
        format_log(generate_measurement(random_hidden_model("pan", ["offset"], 21), duration_s=10.0, seed=3))
    )
    page.click('#tabs button[data-tab="workbench"]')
    page.set_input_files("#upload-file", str(csv))
    page.click("#upload-form button[type=submit]")
    page.wait_for_selector(".dcard", timeout=2 * T)
    verdict = page.text_content("#wb-verdict")
    assert re.search(r"offset|coulomb_asymmetry", verdict), verdict
    assert page.locator("#regime-bars .barrow").count() >= 4
    page.click(".dcard.top button[data-add]")
    page.wait_for_function("window.console3dat_workbench.versions.length === 2", timeout=2 * T)
    rms = page.evaluate("window.console3dat_workbench.versions.map(v => v.fit.rms_deg)")
    assert rms[1] < 0.5 * rms[0]
    assert page.locator("#version-list li").count() == 2
    assert page.locator("#plot-versions canvas").count() == 1


def test_gain_tuning_previews_margins_and_blocks_unsafe_gains(page, server: Server) -> None:  # type: ignore[no-untyped-def]
    page.click('#tabs button[data-tab="tuning"]')
    page.wait_for_selector("#g-kd_v_s_per_rad", timeout=T)
    page.wait_for_function("document.querySelector('#margins .metric') !== null", timeout=T)
    assert "safe to apply" in page.text_content("#margins")
    assert page.locator("#plot-step canvas").count() == 1
    kd = float(page.input_value("#g-kd_v_s_per_rad"))
    page.fill("#g-kd_v_s_per_rad", str(kd * 0.05))
    page.click("#tune-preview")
    page.wait_for_function(
        "document.getElementById('margins').textContent.includes('would be refused')", timeout=T
    )
    assert page.is_disabled("#tune-apply")
    before = server.api("GET", "/axes/pan/gains").json()["gains"]
    assert before["kd_v_s_per_rad"] == pytest.approx(kd, rel=1e-5)


def test_admins_see_the_audit_log_on_the_keys_page(page, server: Server) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function("window.console3dat_status !== undefined", timeout=T)
    tracking = server.api("GET", "/status").json()["tracking"]
    assert server.api("PUT", "/tracking", json={"enabled": tracking}).status_code == 200
    page.click("#tabs button[data-tab=keys]")
    page.wait_for_function(
        "[...document.querySelectorAll('#audit-table code')].some(c => c.textContent === 'tracking.set')",
        timeout=T,
    )
    row = page.text_content("#audit-table tr:nth-child(2)")
    assert "tracking.set" in row and "admin" in row
