"""Settings: defaults, then the TOML file, then TRACKER_* variables, then code; bad values named."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.settings import load_settings
from tracker.errors import ConfigError


def test_file_then_env_then_code(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tmp_path / "console.toml"
    cfg.write_text("port = 9001\nviewer_port = 9002\nmin_phase_margin_deg = 50\n")
    s = load_settings(cfg)
    assert (s.port, s.viewer_port, s.min_phase_margin_deg) == (9001, 9002, 50.0)
    monkeypatch.setenv("TRACKER_PORT", "9100")
    assert load_settings(cfg).port == 9100
    assert load_settings(cfg, port=9200).port == 9200
    assert load_settings(cfg, port=None).port == 9100  # None means "not given"


def test_defaults_run_the_simulated_rig_with_data_in_dot_data() -> None:
    s = load_settings(None)
    assert s.data_dir == Path("data") and s.db_path == Path("data/console.sqlite3")
    assert s.rig_config is None and s.viewer_enabled and s.telemetry_rate_hz >= 50


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("port = 'eighty'\n", ["port", "config file"]),
        ("colour = 'red'\n", ["colour"]),
        ("port = [\n", ["console.toml"]),
        ("telemetry_rate_hz = 10\n", ["telemetry_rate_hz"]),
    ],
    ids=["bad-type", "unknown-key", "bad-toml", "too-slow"],
)
def test_bad_config_is_a_config_error_naming_it(tmp_path: Path, text: str, words: list[str]) -> None:
    cfg = tmp_path / "console.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_settings(cfg)
    for w in words:
        assert w in str(exc.value)


def test_missing_config_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_settings(tmp_path / "nope.toml")


def test_a_bad_rig_file_fails_before_the_server_starts(tmp_path: Path) -> None:
    from app.rig import check_settings

    rig_file = tmp_path / "rig.json"
    rig_file.write_text('{"pan": {"effects": ["warp"]}}')
    with pytest.raises(ConfigError, match="warp"):
        check_settings(load_settings(None, rig_config=str(rig_file)))
    rig_file.write_text('{"pan": {"effects": ["offset"], "params": {"offset.torque": 0.01}}}')
    check_settings(load_settings(None, rig_config=str(rig_file)))


def test_the_site_guard_margin_reaches_the_engine(tmp_path: Path) -> None:
    """A site with a soft belt sets the guard margin in the config file; the engine's soft
    limits use it, and a margin that leaves no room inside the limits is refused by name."""
    import math

    from app.rig import build_engine

    cfg = tmp_path / "console.toml"
    cfg.write_text("guard_margin_deg = 3.0\n")
    engine = build_engine(load_settings(cfg))
    assert engine.config.guard_margin_rad == pytest.approx(math.radians(3.0))
    assert engine.limits("pan").guard_margin_rad == pytest.approx(math.radians(3.0))
    cfg.write_text("guard_margin_deg = 60.0\n")
    with pytest.raises(ConfigError, match="guard_margin_deg"):
        load_settings(cfg)


def test_a_sites_own_effect_loads_before_the_rig_file_that_hides_it(tmp_path: Path) -> None:
    from app.rig import check_settings
    from tracker.plant.effects import CATALOGUE, unregister_effect

    cable = Path(__file__).resolve().parents[2] / "examples" / "effects" / "cable_drag.py"
    rig_file = tmp_path / "rig.json"
    rig_file.write_text('{"pan": {"effects": ["cable_drag"], "params": {"cable_drag.stiffness": 0.02}}}')
    try:
        check_settings(load_settings(None, effects=str(cable), rig_config=str(rig_file)))
        assert "cable_drag" in CATALOGUE
    finally:
        unregister_effect("cable_drag")
    with pytest.raises(ConfigError, match="effects setting: cannot load effect module 'site.nope'"):
        check_settings(load_settings(None, effects="site.nope"))
