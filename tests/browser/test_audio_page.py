"""The console's Audio page in Chromium: the camera operator's settings with their meanings,
a refused value shown with its range, a change applied and kept, the return to the defaults."""

from __future__ import annotations

import pytest

from .conftest import Server

pytestmark = pytest.mark.browser
T = 30_000  # ms


def test_the_policy_panel_shows_meanings_refuses_bad_values_and_applies(page, server: Server  # type: ignore[no-untyped-def]
                                                                        ) -> None:
    page.click('#tabs button[data-tab="audio"]')
    page.wait_for_selector("#pol-min_hold_s", timeout=T)
    names = page.eval_on_selector_all("#policy-form input", "els => els.map(e => e.dataset.name)")
    assert names == ["reaction_time_s", "min_hold_s", "pause_tolerance_s", "deadband_deg",
                     "wide_after_switches", "wide_window_s", "wide_release_s", "lead_s"]
    meanings = page.eval_on_selector_all("#policy-form .meaning", "els => els.map(e => e.textContent)")
    assert len(meanings) == 8 and any("stays on the new talker" in m for m in meanings)
    assert "0–30 s" in page.text_content("#policy-form")

    page.fill("#pol-min_hold_s", "45")
    page.click("#policy-apply")
    page.wait_for_function("document.getElementById('policy-error').textContent.includes('0-30 s')",
                           timeout=T)
    assert server.api("GET", "/audio/policy").json()["values"]["min_hold_s"] == 2.0

    page.fill("#pol-min_hold_s", "4.5")
    page.fill("#pol-deadband_deg", "6")
    page.click("#policy-apply")
    page.wait_for_function("document.getElementById('policy-source').textContent.includes('set here')",
                           timeout=T)
    values = server.api("GET", "/audio/policy").json()["values"]
    assert values["min_hold_s"] == 4.5 and values["deadband_deg"] == 6.0
    assert page.input_value("#pol-min_hold_s") == "4.5"
    page.screenshot(path=str(server.data_dir / "audio-page.png"), full_page=True)

    page.click("#policy-reset")
    page.wait_for_function("document.getElementById('pol-min_hold_s').value === '2'", timeout=T)
    assert server.api("GET", "/audio/policy").json()["source"] == "default"
    assert "Nobody yet" in page.text_content("#talker-list")
