"""The ``tracker`` command line as a whole: help, unknown commands, engine errors as one line."""

import pytest

from tracker.cli import COMMAND_OWNERS, build_parser, main


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
