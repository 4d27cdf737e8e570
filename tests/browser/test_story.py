"""The loop as one story, in Chromium: practice rig → run and record → open in the workbench →
diagnose → add the named effect → the residual panel and the diagnosis agree → the error budget
shows the remainder at the floor; then the command line reads the same history from the console's
database and reproduces it from the same data."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tracker.cli import main
from tracker.workbench.version_db import ConsoleDatabase

from .conftest import Server

pytestmark = pytest.mark.browser
T = 30_000  # ms
SEED = 1  # the practice rig's draw: gravity on the tilt axis


def test_practice_to_the_floor_and_the_cli_tells_the_same_story(  # type: ignore[no-untyped-def]
    page, server: Server, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert server.api("POST", "/practice", json={"axis": "tilt", "seed": SEED}).status_code == 201
    page.click('#tabs button[data-tab="practice"]')
    page.wait_for_function(
        "document.getElementById('practice-state').textContent.includes('tilt')", timeout=T
    )
    page.click("#practice-exp button[type=submit]")  # run and record: steps + ramps + sweep, 20 s
    page.wait_for_selector("#practice-meas [data-open]", timeout=6 * T)
    page.click("#practice-meas [data-open]")
    page.wait_for_function("window.console3dat_workbench.versions.length === 1", timeout=2 * T)
    # version 1 misses something: the residual test and the budget say so before any diagnosis
    page.wait_for_selector('#resid-note[data-consistent="no"]', timeout=4 * T)
    assert page.get_attribute("#budget-verdict", "data-at-floor") == "no"
    assert "left above the floor" in page.text_content("#wb-budget")

    page.click("#wb-diagnose")
    page.wait_for_selector(".dcard", timeout=6 * T)
    verdict = page.text_content("#wb-verdict")
    assert "Most likely missing: gravity" in verdict, verdict
    assert "agree" in verdict and "differ" not in verdict, verdict  # the residual panel says the same

    page.click(".dcard.top button[data-add]")
    page.wait_for_function("window.console3dat_workbench.versions.length === 2", timeout=6 * T)
    # after the add: compare, then the diagnosis again (workbench.js addEffect)
    page.wait_for_function(
        "document.getElementById('wb-verdict').textContent.startsWith('Nothing significant')", timeout=8 * T
    )
    verdict = page.text_content("#wb-verdict")
    assert "agree: nothing is missing" in verdict, verdict  # the diagnosis card ...
    assert page.get_attribute("#resid-note", "data-consistent") == "yes"  # ... and the residual panel
    assert "Residual consistent with a right model" in page.text_content("#resid-verdict")
    assert page.get_attribute("#budget-verdict", "data-at-floor") == "yes"  # ... and the budget
    assert "At the floor" in page.text_content("#budget-verdict")
    budget = page.evaluate("window.console3dat_workbench.versions[1].fit.budget")
    assert budget["consistent"] and budget["rms_deg"] < 1.5 * budget["floor_deg"]
    # the effect explained nearly all of version 1's error: the stacked bar shows it
    v1 = page.evaluate("window.console3dat_workbench.versions[0].fit.budget")
    explained = budget["explained"][0]
    assert explained["change"] == "+gravity" and explained["deg"] ** 2 > 0.95 * v1["rms_deg"] ** 2
    assert page.locator("#wb-budget svg rect").count() >= 8  # two stacked bars
    assert page.locator('#wb-budget rect[data-part="explained by +gravity"]').count() == 1
    versions = page.evaluate("window.console3dat_workbench.versions")
    mid = versions[0]["measurement_id"]
    # STORY_SCREENSHOT=FILE.png keeps a picture of the page (docs/img/console-budget.png came from it)
    page.screenshot(
        path=os.environ.get("STORY_SCREENSHOT", str(server.data_dir / "story.png")), full_page=True
    )

    # the command line: the same history from the console's database ...
    db = server.data_dir / "console.sqlite3"
    png = tmp_path / "history.png"
    assert (
        main(["model", "history", "--db", str(db), "--measurement", str(mid), "--json", "--plot", str(png)])
        == 0
    )
    hist = json.loads(capsys.readouterr().out.splitlines()[0])["versions"]
    assert [v["change"] for v in hist] == ["base", "+gravity"]
    for shown, kept in zip(versions, hist, strict=True):
        assert kept["rms_deg"] == pytest.approx(shown["fit"]["rms_deg"])
        assert kept["budget"]["floor_deg"] == pytest.approx(shown["fit"]["budget"]["floor_deg"])
    assert png.stat().st_size > 20_000
    # ... and reproduced from the same data in a workspace of its own
    with ConsoleDatabase(db) as cdb:
        csv = tmp_path / "practice.csv"
        csv.write_text(cdb.measurement_text(mid))
    ws = str(tmp_path / "ws")
    assert main(["model", "fit", str(csv), "--axis", "tilt", "--workspace", ws]) == 0
    assert main(["model", "fit", str(csv), "--axis", "tilt", "--effects", "gravity", "--workspace", ws]) == 0
    capsys.readouterr()
    assert main(["model", "history", str(csv), "--workspace", ws, "--json"]) == 0
    mine = json.loads(capsys.readouterr().out)["versions"]
    assert [v["change"] for v in mine] == ["base", "+gravity"]
    for shown, redone in zip(versions, mine, strict=True):
        assert redone["rms_deg"] == pytest.approx(shown["fit"]["rms_deg"], rel=1e-6)
        assert redone["budget"]["at_floor"] == shown["fit"]["budget"]["at_floor"]
