"""`tracker model diagnose`: the JSON contract, the readable cards and one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tracker.cli import main
from tracker.workbench.measurements.data import write_log

from ..hidden_cases import hidden_case


@pytest.fixture(scope="module")
def delay_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    _, meas = hidden_case(("delay",), 107)
    p = tmp_path_factory.mktemp("diag") / "delay.csv"
    write_log(p, meas)
    return p


def test_json_follows_the_contract(delay_log: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "diagnose", str(delay_log), "--axis", "pan", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert isinstance(out["fit_percent"], float)
    assert out["verdict"] == "delay"
    first = out["candidates"][0]
    assert first["effect"] == "delay" and first["significant"] is True
    assert set(first["params"]) == {"delay.seconds"}
    assert isinstance(first["evidence"], str) and "ms" in first["evidence"]
    assert all(isinstance(c["fit_percent"], float) for c in out["candidates"])


def test_model_that_has_the_effect_is_not_told_to_grow(
    delay_log: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, meas = hidden_case(("delay",), 107)
    true, _ = hidden_case(("delay",), 107)
    d = true.params["delay.seconds"]
    assert (
        main(
            [
                "model",
                "diagnose",
                str(delay_log),
                "--axis",
                "pan",
                "--effects",
                "delay",
                "--set",
                f"delay.seconds={d}",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] is None
    assert "delay" not in {c["effect"] for c in out["candidates"]}


def test_text_output_is_ranked_cards(delay_log: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "diagnose", str(delay_log), "--axis", "pan"]) == 0
    text = capsys.readouterr().out
    assert "VERDICT: the model is missing delay" in text
    assert "1. delay" in text and "delay.seconds =" in text


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("t,u\n0,1\n", "missing column theta"),
        ("t,u,theta\n" + "".join(f"{i * 1e-3},0,nan\n" for i in range(300)), "line 2"),
    ],
    ids=["missing-column", "nan"],
)
def test_bad_input_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, needle: str
) -> None:
    p = tmp_path / "bad.csv"
    p.write_text(content)
    assert main(["model", "diagnose", str(p), "--axis", "pan"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and needle in err and err.count("\n") == 1


def test_a_log_where_the_axis_never_moves_is_an_error_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = tmp_path / "still.csv"
    p.write_text("t,u,theta\n" + "".join(f"{i * 1e-3},0.1,0\n" for i in range(2000)))
    assert main(["model", "diagnose", str(p), "--axis", "pan"]) == 2
    assert "usable moving samples" in capsys.readouterr().err
