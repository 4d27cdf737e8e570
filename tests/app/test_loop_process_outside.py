"""Found by running the console as a user would, with ``loop_process = true`` (and checked
against the loop in a thread): each test here failed before its fix."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.app.conftest import make_rig
from tests.tracker.audio.conftest import FS_HZ, example_array, free_field
from tracker.audio.sources import write_wav

API = "/api/v1"


def one_talker_wav(path: Path) -> Path:
    """A talker at 20° for 2 s on the 4-mic square (16 kHz)."""
    array = example_array("square4_65mm")
    quiet = 0.001 * np.random.default_rng(0).standard_normal((4, FS_HZ // 2))
    audio = np.concatenate([quiet, free_field(array, math.radians(20.0), duration_s=2.0, seed=1)], axis=1)
    write_wav(path, FS_HZ, audio)
    return path


def status(rig: Any) -> dict[str, Any]:  # noqa: ANN401 - the conftest's Rig
    r = rig.client.get(f"{API}/status", headers=rig.h("viewer"))
    assert r.status_code == 200, r.text
    out: dict[str, Any] = r.json()
    return out


@pytest.mark.parametrize("loop_process", [True, False], ids=["process", "thread"])
def test_tracking_turned_off_stays_off_after_a_restart_with_audio(tmp_path: Path, loop_process: bool) -> None:
    """Bug: with the room's audio on (the default) ``track_on_start`` turned tracking on at every
    start, after the stored "tracking off" had been restored (docs/operations.md: tracking on/off
    survives a restart). ``track_on_start`` is for a fresh start, with nothing stored."""
    wav = one_talker_wav(tmp_path / "talker.wav")
    data = tmp_path / "data"
    data.mkdir()
    settings = {"audio_enabled": True, "audio_input": f"wav:{wav}", "loop_process": loop_process}
    for rig in make_rig(data, **settings):
        assert status(rig)["tracking"] is True  # a fresh start follows the talker
        r = rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": False})
        assert r.status_code == 200 and r.json()["tracking"] is False, r.text
    for rig in make_rig(data, **settings):
        st = status(rig)
        assert st["tracking"] is False and st["settings_warnings"] == [], st
