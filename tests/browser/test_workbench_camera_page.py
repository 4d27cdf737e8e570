"""The workbench page on a PTZ camera log: upload, the camera diagnosis cards naming the
hidden latency, the regime bars of the camera compare; adding the latency makes version 2, whose
error fell and whose diagnosis has nothing left to add."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from tests.tracker.workbench.camera.ptz_log_generator import generate, random_truth, to_csv

from .conftest import Server

pytestmark = pytest.mark.browser
T = 30_000  # ms (a camera diagnosis is tens of seconds on a loaded 2-core machine)


def test_camera_log_upload_shows_the_camera_diagnosis(page, server: Server, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    csv = tmp_path / "ptz_run.csv"
    csv.write_text(to_csv(*generate(random_truth(random.Random(7), latency=True), 45.0, 7)))
    page.click('#tabs button[data-tab="workbench"]')
    page.set_input_files("#upload-file", str(csv))
    page.click("#upload-form button[type=submit]")
    page.wait_for_selector(".dcard", timeout=6 * T)
    verdict = page.text_content("#wb-verdict") or ""
    assert "Camera log" in verdict and "latency" in verdict, verdict
    assert "latency" in (page.text_content(".dcard.top h3") or "")
    assert "camera log" in (page.text_content("#wb-title") or "")
    assert page.locator("#regime-bars .barrow").count() >= 3
    assert page.locator("#wb-fit").is_enabled() and page.locator("#wb-design").is_disabled()
    assert page.text_content("#upload-error") == ""
    assert page.locator("#version-list li").count() == 1

    page.click(".dcard.top button[data-add]")
    page.wait_for_function(
        "document.querySelector('#wb-title').textContent.includes('+latency (v2)')", timeout=6 * T
    )
    assert page.locator("#version-list li").count() == 2
    page.wait_for_function(
        "document.querySelector('#wb-verdict').textContent.includes('Nothing significant')", timeout=2 * T
    )
    rms = page.evaluate("window.console3dat_workbench.versions.map((v) => v.fit.rms_deg)")
    assert rms[1] < 0.5 * rms[0], rms
