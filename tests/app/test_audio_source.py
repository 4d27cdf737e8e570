"""The simulated meeting as target source: table playback on engine time, looping, caching."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from app.audio import MeetingSource, TrackTable


def table() -> TrackTable:
    nan = math.nan
    return TrackTable(
        end_s=np.array([0.5, 0.6, 0.7, 0.8]),
        target_az_rad=np.array([nan, 0.3, 0.3, -0.2]),
        talker_az_rad=np.array([nan, 0.31, nan, -0.2]),
        estimate_az_rad=np.array([nan, 0.29, 0.35, nan]),
        estimate_el_rad=np.array([nan, 0.05, nan, nan]),
        duration_s=10.0,
    )


def test_nothing_before_the_first_window_or_the_first_shot() -> None:
    src = MeetingSource(table())
    assert src.target_at(0.2) is None  # no window has ended
    assert src.target_at(0.55) is None  # a window, but no shot yet


def test_each_window_applies_from_its_end_until_the_next() -> None:
    src = MeetingSource(table())
    t = src.target_at(0.65)
    assert t is not None
    assert (t.pan_rad, t.azimuth_rad, t.elevation_rad) == pytest.approx((0.3, 0.29, 0.05))
    assert t.talker == f"talker at {math.degrees(0.31):+.0f}°"
    wide = src.target_at(0.75)
    assert wide is not None and wide.talker == "wide shot" and wide.elevation_rad is None
    last = src.target_at(5.0)
    assert last is not None and last.pan_rad == pytest.approx(-0.2) and last.azimuth_rad is None


def test_the_meeting_loops_on_engine_time() -> None:
    src = MeetingSource(table())
    a, b = src.target_at(0.65), src.target_at(10.65)
    assert a is not None and b is not None and a.pan_rad == b.pan_rad


def test_not_ready_says_nothing() -> None:
    assert MeetingSource(None).target_at(3.0) is None


def test_cache_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "m.npz"
    table().save(path)
    back = TrackTable.load(path)
    assert back is not None and back.duration_s == 10.0
    np.testing.assert_array_equal(back.target_az_rad, table().target_az_rad)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    assert TrackTable.load(tmp_path / "bad.npz") is None


def test_the_engine_follows_the_meeting_source() -> None:
    import asyncio

    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    engine = Engine(SimDriver())
    engine.set_target_source(MeetingSource(table()))
    engine.set_tracking(True)
    asyncio.run(engine.run(realtime=False, duration_s=4.0))  # the last window says -0.2 rad
    st = engine.status()
    assert st.mode == "tracking" and st.active_talker == f"talker at {math.degrees(-0.2):+.0f}°"
    assert st.pan_rad == pytest.approx(-0.2, abs=0.01)
    assert st.tilt_rad == pytest.approx(0.0, abs=0.01)
