"""``tracker model compare|fit``: the JSON contract, readable tables, one-line errors."""

import json
from pathlib import Path

import pytest

from tracker.cli import main
from tracker.plant.model import AxisModel
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.measurements.data import write_log


@pytest.fixture(scope="module")
def log_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    true = AxisModel.for_axis("pan", ["quantization", "offset"], {"offset.torque": 0.01})
    path = tmp_path_factory.mktemp("cli") / "run.csv"
    write_log(path, closed_loop_log(true, duration_s=10.0, seed=2))
    return path


def test_compare_json_contract(log_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "compare", str(log_path), "--axis", "pan", "--effects", "offset", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert isinstance(d["fit_percent"], float) and isinstance(d["rms_deg"], float)
    assert {"rms_deg", "share_of_error_percent", "samples", "fraction_of_time"} <= set(
        d["regimes"]["reversal"]
    )


def test_fit_json_contract_has_every_parameter(log_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "fit", str(log_path), "--axis", "pan", "--effects", "offset", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert set(d["params"]) == set(AxisModel.for_axis("pan", ["offset"]).params)
    assert set(d["stderr"]) == {"inertia.J", "viscous.b", "coulomb.torque", "offset.torque"}
    assert d["params"]["offset.torque"] == pytest.approx(0.01, rel=0.1)


def test_tables_for_people(log_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "compare", str(log_path), "--axis", "tilt"]) == 0
    out = capsys.readouterr().out
    assert "reversal" in out and "fit" in out
    assert main(["model", "fit", str(log_path), "--axis", "pan", "--gain", "0.07416"]) == 0
    out = capsys.readouterr().out
    assert "coulomb.torque" in out and "±" in out


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("t,u\n0,1\n", "missing column theta"),
        (
            "t,u,theta\n" + "".join(f"{i * 1e-3},0,{'x' if i == 5 else 0}\n" for i in range(300)),
            "line 7: theta",
        ),
        ("t,u,theta\n" + "".join(f"{i * 1e-3},0,{'nan' if i == 3 else 0}\n" for i in range(300)), "line 5"),
        (
            "t,u,theta\n" + "".join(f"{(i if i != 9 else 8) * 1e-3},0,0\n" for i in range(300)),
            "time does not increase",
        ),
        (
            "t,u,theta\n" + "".join(f"{i * 1e-3 * (2 if i > 100 else 1)},0,0\n" for i in range(300)),
            "uneven sampling",
        ),
        ("t,u,theta\n0,0,0\n0.001,0,0\n", "only 2 samples"),
    ],
    ids=["missing-column", "non-numeric", "nan", "time-backwards", "uneven", "too-short"],
)
def test_bad_data_is_one_line_naming_the_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, needle: str
) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(content, encoding="utf-8")
    assert main(["model", "fit", str(bad), "--axis", "pan", "--json"]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--effects", "flux_capacitor"], "unknown effect 'flux_capacitor'"),
        (["--gain", "-1"], "--gain"),
        (["--set", "inertia.J"], "NAME=VALUE"),
        (["--set", "inertia.J=-5"], "inertia.J"),
    ],
    ids=["unknown-effect", "bad-gain", "bad-set", "out-of-bounds"],
)
def test_bad_options_are_one_line_errors(
    log_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], needle: str
) -> None:
    assert main(["model", "compare", str(log_path), "--axis", "pan", *args]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1


@pytest.fixture(autouse=True)
def _workspace_in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`fit` keeps versions in ./.tracker-workspace: keep them out of the checkout."""
    monkeypatch.chdir(tmp_path)


def test_fit_keeps_versions_and_history_shows_the_error_falling(
    log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ws = str(tmp_path / "ws")
    assert main(["model", "fit", str(log_path), "--axis", "pan", "--workspace", ws]) == 0
    assert "kept as version 1 (base)" in capsys.readouterr().out
    assert (
        main(["model", "fit", str(log_path), "--axis", "pan", "--effects", "offset", "--workspace", ws]) == 0
    )
    assert "kept as version 2 (+offset)" in capsys.readouterr().out
    assert main(["model", "history", str(log_path), "--workspace", ws, "--replicas", "0", "--json"]) == 0
    hist = json.loads(capsys.readouterr().out)
    assert [v["change"] for v in hist["versions"]] == ["base", "+offset"]
    assert main(["model", "history", str(log_path), "--workspace", ws, "--replicas", "3"]) == 0
    out = capsys.readouterr().out
    assert "error budget" in out and "explained by +offset" in out


def test_history_without_versions_is_one_error_line(
    log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["model", "history", str(log_path), "--workspace", str(tmp_path / "empty")]) == 2
    assert "no versions" in capsys.readouterr().err


def test_plot_writes_the_consoles_pictures_and_refuses_other_names(
    log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "compare.png"
    args = ["model", "compare", str(log_path), "--axis", "pan", "--replicas", "2"]
    assert main([*args, "--plot", str(png)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 20_000
    assert main([*args, "--plot", str(tmp_path / "compare.pdf")]) == 2
    assert "give a .png file name" in capsys.readouterr().err
    assert main([*args, "--plot", str(tmp_path / "no" / "such" / "x.png")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_the_plotting_module_is_imported_only_for_plot() -> None:
    """(matplotlib itself comes with python-control; the pictures' module and backend only with --plot)"""
    import subprocess
    import sys

    code = (
        "import sys, tracker.cli.model, tracker.cli.model_history; "
        "print('tracker.workbench.plots' in sys.modules)"
    )
    root = Path(__file__).resolve().parents[3]
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root)
    assert run.stdout.strip() == "False"
