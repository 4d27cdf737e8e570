"""The workbench page on a PTZ camera log: upload, the camera diagnosis cards naming the
hidden latency, the regime bars of the camera compare; fit is not offered for it."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from tests.tracker.workbench.camera.ptz_log_generator import generate, random_truth, to_csv

from .conftest import Server

pytestmark = pytest.mark.browser
T = 30_000  # ms


def test_camera_log_upload_shows_the_camera_diagnosis(page, server: Server, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    csv = tmp_path / "ptz_run.csv"
    csv.write_text(to_csv(*generate(random_truth(random.Random(7), latency=True), 45.0, 7)))
    page.click('#tabs button[data-tab="workbench"]')
    page.set_input_files("#upload-file", str(csv))
    page.click("#upload-form button[type=submit]")
    page.wait_for_selector(".dcard", timeout=2 * T)
    verdict = page.text_content("#wb-verdict") or ""
    assert "Camera log" in verdict and "latency" in verdict, verdict
    assert "latency" in (page.text_content(".dcard.top h3") or "")
    assert page.locator(".dcard.top button[data-add]").is_disabled()
    assert "camera log" in (page.text_content("#wb-title") or "")
    assert page.locator("#regime-bars .barrow").count() >= 3
    assert page.locator("#wb-fit").is_disabled()
    assert page.text_content("#upload-error") == ""
