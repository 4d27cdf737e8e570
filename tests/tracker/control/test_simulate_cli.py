"""``tracker simulate``: the issue's JSON keys, hidden effects, recording to the log format."""

import json
from pathlib import Path

import pytest

from tracker.cli import main
from tracker.workbench.measurements.data import read_log

ISSUE_KEYS = {
    "phase_margin_deg",
    "gain_margin_db",
    "rise_time_s",
    "overshoot_percent",
    "settling_time_s",
    "sine_1hz_peak_error_percent",
}


def test_simulate_json_reports_the_issue_keys_and_records_a_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "run.csv"
    assert main(["simulate", "--axis", "tilt", "--effects", "offset", "--record", str(log), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"tilt"}
    assert ISSUE_KEYS <= set(out["tilt"])
    assert "offset" in out["tilt"]["twin_effects"]
    m = read_log(log)
    assert m.n == 20000 and m.dt_s == pytest.approx(1e-3)


def test_simulate_refuses_a_duration_shorter_than_the_script(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--duration", "5"]) == 2
    assert "at least 20" in capsys.readouterr().err


def test_simulate_refuses_an_unknown_effect(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--axis", "pan", "--effects", "warp"]) == 2
    assert "unknown effect 'warp'" in capsys.readouterr().err


def test_param_reaches_the_twin(capsys: pytest.CaptureFixture[str]) -> None:
    """Regression: --param was parsed but not passed on, so gravity stayed at its 0 default."""
    figures = []
    for extra in ([], ["--param", "gravity.torque=0.05"]):
        assert main(["simulate", "--axis", "tilt", "--json", *extra]) == 0
        figures.append(json.loads(capsys.readouterr().out)["tilt"])
    assert "gravity" in figures[1]["twin_effects"]
    assert figures[1]["sine_1hz_peak_error_percent"] > 1.5 * figures[0]["sine_1hz_peak_error_percent"]


def test_param_must_be_name_equals_number(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--param", "gravity.torque"]) == 2
    assert "EFFECT.PARAM=NUMBER" in capsys.readouterr().err
