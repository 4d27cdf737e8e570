"""The ``tracker`` command line as a whole: help, unknown commands, engine errors as one line."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tracker.cli import COMMAND_OWNERS, build_parser, main

ROOT = Path(__file__).resolve().parents[2]


def test_top_level_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for command in COMMAND_OWNERS:
        assert command in out


@pytest.mark.parametrize("command", sorted(COMMAND_OWNERS))
def test_each_command_has_working_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser(command)
    with pytest.raises(SystemExit) as exc:
        parser.parse_args([command, "--help"])
    assert exc.value.code == 0
    assert command in capsys.readouterr().out


def test_no_command_prints_help_and_fails(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 1
    assert "COMMAND" in capsys.readouterr().out


def test_serve_passes_the_rig_config_to_the_console(monkeypatch: pytest.MonkeyPatch) -> None:
    """Regression: ``tracker serve --rig-config`` was ignored whenever the console ran."""
    import app.main

    seen: dict[str, object] = {}
    monkeypatch.setattr(app.main, "run_server", lambda **kw: seen.update(kw))
    assert main(["serve", "--port", "8123", "--rig-config", "rig.json"]) == 0
    assert seen["rig_config"] == "rig.json"
    assert seen["port"] == 8123


HEAVY = ("scipy", "numba", "control", "pyroomacoustics", "matplotlib", "app", "fastapi")


@pytest.mark.parametrize("argv", [["--help"], ["audio", "locate", "--help"], ["simulate", "--help"],
                                  ["serve", "--help"], ["friction-id", "--help"]],
                         ids=lambda a: " ".join(a))
def test_help_imports_no_heavy_module(argv: list[str]) -> None:
    """Start-up (issue 12): ``tracker --help`` took 1.7-4 s importing every command's engine;
    a command's help now imports only its own light module (numpy at most)."""
    code = ("import sys\nfrom tracker.cli import main\ntry:\n    main(sys.argv[1:])\n"
            "except SystemExit:\n    pass\n"
            f"print('LOADED:' + ','.join(m for m in {(*HEAVY, 'numpy')!r} if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                         check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    loaded = out.stdout.strip().splitlines()[-1].removeprefix("LOADED:").split(",")
    assert not set(loaded) & set(HEAVY), loaded
    if argv == ["--help"]:
        assert "numpy" not in loaded  # the standard library only


def test_an_unknown_controller_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--controller", "pid", "--duration", "1"]) == 2
    assert "pid" in capsys.readouterr().err
