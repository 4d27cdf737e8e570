"""The room's audio on the API: the camera operator's policy (read, set, refused, reset, stored,
applied to the running stream), the talkers followed, the input devices, live capture's fault."""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.settings import load_settings
from tests.app.conftest import Rig, make_rig, poll
from tests.tracker.audio.conftest import FS_HZ, example_array, free_field
from tests.tracker.audio.fake_sounddevice import FakeBackend
from tracker.audio.sources import write_wav
from tracker.errors import ConfigError

DEFAULTS = {"reaction_time_s": 0.2, "min_hold_s": 2.0, "pause_tolerance_s": 1.5, "deadband_deg": 3.0,
            "wide_after_switches": 4, "wide_window_s": 20.0, "wide_release_s": 6.0, "lead_s": 0.3}


@contextlib.contextmanager
def running(tmp: Path, **overrides: Any) -> Iterator[Rig]:
    """A service on ``tmp`` for the ``with`` block (stopped at its end)."""
    gen = make_rig(tmp, **overrides)
    try:
        yield next(gen)
    finally:
        gen.close()


@pytest.fixture
def fresh(tmp_path: Path) -> Any:
    yield from make_rig(tmp_path)


def test_viewers_read_the_policy_with_each_settings_meaning(rig: Rig) -> None:
    r = rig.client.get("/api/v1/audio/policy", headers=rig.h("viewer"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["values"] == DEFAULTS and body["source"] == "default"
    fields = {f["name"]: f for f in body["fields"]}
    assert list(fields) == list(DEFAULTS)
    assert fields["deadband_deg"]["unit"] == "deg" and fields["deadband_deg"]["max"] == 30.0
    assert fields["min_hold_s"] == {"name": "min_hold_s", "unit": "s", "min": 0.0, "max": 30.0,
                                    "default": 2.0, "meaning": fields["min_hold_s"]["meaning"]}
    assert all(len(f["meaning"]) > 30 for f in fields.values())


def test_only_engineers_change_it(fresh: Rig) -> None:
    for role in ("viewer", "operator"):
        r = fresh.client.put("/api/v1/audio/policy", json={"min_hold_s": 4.0}, headers=fresh.h(role))
        assert r.status_code == 403
    assert fresh.client.delete("/api/v1/audio/policy", headers=fresh.h("operator")).status_code == 403


def test_a_change_round_trips_and_a_reset_forgets_it(fresh: Rig) -> None:
    h = fresh.h("engineer")
    r = fresh.client.put("/api/v1/audio/policy", json={"min_hold_s": 4.5, "deadband_deg": 5,
                                                       "wide_after_switches": 6}, headers=h)
    assert r.status_code == 200, r.text
    want = {**DEFAULTS, "min_hold_s": 4.5, "deadband_deg": 5.0, "wide_after_switches": 6}
    assert r.json()["values"] == want and r.json()["source"] == "stored"
    got = fresh.client.get("/api/v1/audio/policy", headers=fresh.h("viewer")).json()
    assert got["values"] == want
    svc = fresh.client.app.state.svc  # type: ignore[attr-defined]
    assert svc.policy.policy.deadband_rad == pytest.approx(math.radians(5.0))
    r = fresh.client.put("/api/v1/audio/policy", json={"lead_s": 0.0}, headers=h)
    assert r.json()["values"] == {**want, "lead_s": 0.0}
    r = fresh.client.delete("/api/v1/audio/policy", headers=h)
    assert r.status_code == 200 and r.json() == {**got, "values": DEFAULTS, "source": "default"}


@pytest.mark.parametrize(
    ("body", "field", "words"),
    [({"min_hold_s": 45}, "min_hold_s", ["min_hold_s=45", "0-30 s", "stays on the new talker"]),
     ({"deadband_deg": 31.5}, "deadband_deg", ["deadband_deg=31.5", "0-30°"]),
     ({"wide_after_switches": 2.5}, "wide_after_switches", ["a whole number", "2-50"]),
     ({"reaction_time_s": "fast"}, "reaction_time_s", ["'fast'", "0.05-3 s"]),
     ({"lead_s": 10**400}, "lead_s", ["lead_s=", "0-2 s"]),
     ({"lead_s": None}, "lead_s", ["lead_s=None"]),
     ({"min_hold_s": 3.0, "pause_tolerance_s": 0.0}, "pause_tolerance_s", ["0.2-10 s"])],
    ids=["hold", "deadband", "count", "string", "huge", "null", "one-of-two"],
)
def test_a_bad_value_is_a_422_naming_the_field_and_its_range_and_nothing_changes(
        fresh: Rig, body: dict[str, Any], field: str, words: list[str]) -> None:
    r = fresh.client.put("/api/v1/audio/policy", json=body, headers=fresh.h("engineer"))
    assert r.status_code == 422, r.text
    err = r.json()
    assert err["field"] == field and err["error"] == "Refused"
    assert set(err["allowed"]) == {"min", "max", "unit"}
    for word in words:
        assert word in err["detail"]
    got = fresh.client.get("/api/v1/audio/policy", headers=fresh.h("viewer")).json()
    assert got["values"] == DEFAULTS and got["source"] == "default"


def test_an_unknown_setting_is_a_422_naming_it(fresh: Rig) -> None:
    r = fresh.client.put("/api/v1/audio/policy", json={"min_hold": 3}, headers=fresh.h("engineer"))
    assert r.status_code == 422 and "min_hold" in r.json()["detail"]


def test_the_stored_policy_survives_a_restart(tmp_path: Path) -> None:
    with running(tmp_path) as rig:
        r = rig.client.put("/api/v1/audio/policy", json={"min_hold_s": 7.0, "deadband_deg": 1.5},
                           headers=rig.h("engineer"))
        assert r.status_code == 200
    with running(tmp_path, camera_policy={"min_hold_s": 3.0, "lead_s": 0.5}) as rig:
        got = rig.client.get("/api/v1/audio/policy", headers=rig.h("viewer")).json()
        # stored values win; the config file's others still count
        assert got["values"] == {**DEFAULTS, "min_hold_s": 7.0, "deadband_deg": 1.5, "lead_s": 0.5}
        assert got["source"] == "stored"
        r = rig.client.delete("/api/v1/audio/policy", headers=rig.h("engineer"))
        assert r.json()["values"] == {**DEFAULTS, "min_hold_s": 3.0, "lead_s": 0.5}
        assert r.json()["source"] == "config"


def test_the_config_file_and_environment_set_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "site.toml"
    config.write_text("[camera_policy]\nmin_hold_s = 3\ndeadband_deg = 4.5\n")
    assert load_settings(config).camera_policy == {"min_hold_s": 3.0, "deadband_deg": 4.5}
    monkeypatch.setenv("TRACKER_CAMERA_POLICY", json.dumps({"reaction_time_s": 0.4}))
    assert load_settings(None).camera_policy == {"reaction_time_s": 0.4}


@pytest.mark.parametrize(
    ("text", "words"),
    [("[camera_policy]\nmin_hold_s = 99\n", ["camera_policy", "config file", "min_hold_s=99", "0-30 s"]),
     ("[camera_policy]\nhold = 3\n", ["camera_policy", "unknown setting(s) hold", "min_hold_s"])],
    ids=["range", "unknown"],
)
def test_a_bad_policy_in_the_config_file_stops_start_up_naming_it(
        tmp_path: Path, text: str, words: list[str]) -> None:
    config = tmp_path / "site.toml"
    config.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_settings(config)
    for word in words:
        assert word in str(err.value)


def two_talkers_wav(path: Path) -> Path:
    """Talker 1 at 35° for 3 s then talker 2 at -40° for 3 s (4-mic square, 16 kHz)."""
    array = example_array("square4_65mm")
    quiet = 0.001 * np.random.default_rng(0).standard_normal((4, FS_HZ // 2))
    audio = np.concatenate([quiet, free_field(array, math.radians(35.0), duration_s=3.0, seed=1),
                            quiet, free_field(array, math.radians(-40.0), duration_s=3.0, seed=2),
                            quiet], axis=1)
    write_wav(path, FS_HZ, audio)
    return path


def test_a_new_policy_reaches_the_running_stream_and_the_talkers_are_listed(tmp_path: Path) -> None:
    wav = two_talkers_wav(tmp_path / "two.wav")
    with running(tmp_path, audio_enabled=True, audio_input=f"wav:{wav}") as rig:
        svc = rig.client.app.state.svc  # type: ignore[attr-defined]
        loc = poll(lambda: svc.audio.locator, deadline_s=20)
        assert loc is not None and loc._map_tracker is not None
        r = rig.client.put("/api/v1/audio/policy", json={"min_hold_s": 6.0, "deadband_deg": 8},
                           headers=rig.h("engineer"))
        assert r.status_code == 200
        # applied by the stream's thread at its next frame: no restart
        assert poll(lambda: svc.audio.locator._map_tracker.settings.min_hold_s == 6.0, deadline_s=10)
        assert svc.audio.locator._map_tracker.settings.deadband_rad == pytest.approx(math.radians(8))

        def two_talkers() -> list[dict[str, Any]] | None:
            st = rig.client.get("/api/v1/status", headers=rig.h("viewer")).json()
            return st["talkers"] if len(st["talkers"]) >= 2 else None

        talkers = poll(two_talkers, deadline_s=30, interval_s=0.2)
        assert talkers is not None, "the stream never followed both talkers"
        assert abs(talkers[0]["azimuth_deg"] - 35.0) < 4 and abs(talkers[1]["azimuth_deg"] + 40.0) < 4
        assert set(talkers[0]) == {"talker_id", "azimuth_deg", "elevation_deg", "speaking",
                                   "last_spoken_ago_s", "speaking_s"}
        again = rig.client.get("/api/v1/audio/talkers", headers=rig.h("viewer")).json()["talkers"]
        assert [t["talker_id"] for t in again][:2] == [0, 1]


def test_the_device_list_is_empty_with_a_reason_without_portaudio(rig: Rig) -> None:
    assert rig.client.get("/api/v1/audio/devices", headers=rig.h("operator")).status_code == 403
    r = rig.client.get("/api/v1/audio/devices", headers=rig.h("engineer"))
    assert r.status_code == 200
    body = r.json()
    try:
        import sounddevice  # noqa: F401
    except OSError:  # no PortAudio on this machine: no devices, and why
        assert body["devices"] == [] and "PortAudio" in body["note"]


def test_the_device_list_shows_the_cards_inputs(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    import tracker.audio.capture as capture

    monkeypatch.setattr(capture, "sounddevice_backend", lambda: FakeBackend("USB Array", 8, 48000))
    body = rig.client.get("/api/v1/audio/devices", headers=rig.h("engineer")).json()
    assert body == {"devices": [{"index": 1, "name": "USB Array", "host_api": "ALSA",
                                 "max_input_channels": 8, "default_rate_hz": 48000.0,
                                 "default": True}], "note": None}


def test_live_capture_shows_a_missing_device_as_a_fault_and_recovers(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import tracker.audio.capture as capture

    backend = FakeBackend("USB Array", 6, 48000, present=False)
    monkeypatch.setattr(capture, "sounddevice_backend", lambda: backend)
    with running(tmp_path, audio_enabled=True, audio_input="live:USB",
                 audio_channel_map=[5, 2, 0, 3], audio_device_rate_hz=48000) as rig:
        st = rig.client.get("/api/v1/status", headers=rig.h("viewer")).json()
        assert st["audio"].startswith("live capture fault: audio input device 'USB' not found")
        assert "next try in" in st["audio"]
        cap = st["audio_capture"]
        assert cap["state"] == "fault" and cap["channel_map"] == [5, 2, 0, 3]
        backend.present = True

        def capture_running() -> dict[str, Any] | None:
            c = rig.client.get("/api/v1/status", headers=rig.h("viewer")).json()["audio_capture"]
            return c if c["state"] == "running" else None

        cap = poll(capture_running, deadline_s=10)
        assert cap is not None and cap["device"] == "USB Array" and cap["device_rate_hz"] == 48000
        assert cap["device_channels"] == 6 and cap["reconnects"] == 1
        stream = backend.stream
        assert (stream.samplerate, stream.channels, stream.device) == (48000, 6, "USB")
