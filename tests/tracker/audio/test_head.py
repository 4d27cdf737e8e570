"""Head-mounted arrays: head-frame estimates + encoder angles = the talker's base-frame direction."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.audio import room
from tracker.audio.array import MicArray, rotation_world_head, unit_vector
from tracker.audio.head import (
    HeadPoses,
    azimuths_to_base,
    direction_to_base,
    locate_head_mounted,
    map_to_base,
    power_weights,
    read_encoder_log,
)
from tracker.audio.head_room import simulate_head_mounted
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.speech import synthetic_speech
from tracker.audio.stream import StreamingLocator, stream_blocks
from tracker.errors import ConfigError, DataError
from tracker.recording import write_measurements
from tracker.scenarios.meeting import MeetingSettings
from tracker.workbench.measurements.data import Measurement

from .conftest import FS_HZ, angle_error_deg, example_array, free_field

angles = st.floats(-math.pi / 2, math.pi / 2)
tilts = st.floats(-0.7, 0.7)


def head_frame(az_rad: float, el_rad: float, pan_rad: float, tilt_rad: float) -> tuple[float, float]:
    """Where a base-frame direction lies in the head frame (the inverse rotation)."""
    u = rotation_world_head(pan_rad, tilt_rad).T @ unit_vector(az_rad, el_rad)
    return math.atan2(u[1], u[0]), math.asin(u[2])


@settings(max_examples=200, deadline=None)
@given(az=st.floats(-math.pi, math.pi), el=st.floats(-1.2, 1.2), pan=angles, tilt=tilts)
def test_a_head_frame_direction_returns_to_its_base_direction(az, el, pan, tilt):
    az_h, el_h = head_frame(az, el, pan, tilt)
    base_az, base_el = direction_to_base(az_h, el_h, rotation_world_head(pan, tilt))
    assert base_el is not None
    assert base_el == pytest.approx(el, abs=1e-9)
    assert angle_error_deg(base_az, az) < 1e-6


@settings(max_examples=200, deadline=None)
@given(az=st.floats(-math.pi, math.pi), pan=angles, tilt=tilts)
def test_a_flat_array_on_a_tilted_head_finds_an_eye_level_talker(az, pan, tilt):
    """A flat array measures only the head-frame azimuth; a talker at the array's height is
    recovered exactly (adding the pan alone is wrong once the head tilts)."""
    az_h, _ = head_frame(az, 0.0, pan, tilt)
    base_az, base_el = direction_to_base(az_h, None, rotation_world_head(pan, tilt))
    assert base_el is None
    assert angle_error_deg(base_az, az) < 1e-6
    if tilt == 0.0:
        assert angle_error_deg(base_az, az_h + pan) < 1e-9


@settings(max_examples=100, deadline=None)
@given(az=st.floats(-math.pi, math.pi), pan=angles, tilt=tilts)
def test_head_map_cells_land_where_a_flat_arrays_estimate_would(az, pan, tilt):
    """The vectorised cell mapping is :func:`direction_to_base`'s flat case, cell by cell."""
    r = rotation_world_head(pan, tilt)
    cells = np.array([az, 0.5 * az, -az])
    expected = [direction_to_base(float(a), None, r)[0] for a in cells]
    for got, want in zip(azimuths_to_base(cells, r), expected, strict=True):
        assert angle_error_deg(float(got), want) < 1e-9


def bump(grid_rad: np.ndarray, centre_rad: float) -> np.ndarray:
    """A smooth circular peak at ``centre_rad`` (a talker's steered response)."""
    return np.exp(4.0 * (np.cos(grid_rad - centre_rad) - 1.0))


@settings(max_examples=100, deadline=None)
@given(az=st.floats(-math.pi, math.pi), pan=st.floats(-math.pi, math.pi), tilt=tilts)
def test_a_full_circle_head_map_moves_its_peak_to_the_talkers_base_azimuth(az, pan, tilt):
    """An eye-level talker at base azimuth ``az``: her head-frame peak, turned with the head's
    rotation, peaks at ``az`` on any base grid, across ±180° too."""
    head_grid = np.arange(-math.pi, math.pi, math.radians(1.0))
    az_h, _ = head_frame(az, 0.0, pan, tilt)
    base_grid = np.linspace(az - 1.0, az + 1.0, 121)  # may run past ±180°
    base = map_to_base(bump(head_grid, az_h), head_grid, base_grid, rotation_world_head(pan, tilt))
    assert base.shape == base_grid.shape
    assert angle_error_deg(float(base_grid[np.argmax(base)]), az) < 1.0


def test_base_cells_the_head_grid_does_not_reach_hold_the_maps_minimum():
    head_grid = np.radians(np.arange(-90.0, 90.5, 1.0))  # a front-only head-frame search
    power = bump(head_grid, math.radians(20.0))
    base_grid = np.radians(np.arange(-180.0, 180.0, 1.0))
    base = map_to_base(power, head_grid, base_grid, rotation_world_head(math.radians(60.0), 0.0))
    deg = np.degrees(base_grid)
    assert deg[np.argmax(base)] == pytest.approx(80.0, abs=0.5)  # 20° + the pan
    unheard = (deg < -30.0) | (deg > 150.0)  # outside 60° ± 90°
    np.testing.assert_array_equal(base[unheard], power.min())
    assert np.all(base[~unheard] >= power.min())


def test_the_mean_rotation_over_a_turn_is_the_middle_of_the_turn():
    poses = HeadPoses.from_arrays(np.array([0.0, 1.0]), np.radians([0.0, 60.0]), np.zeros(2))
    motion = poses.motion_over(0.4, 0.6)  # the head turns 12° in this window, uniform weights
    az, _ = direction_to_base(0.0, None, motion.r_world_head)
    assert math.degrees(az) == pytest.approx(30.0, abs=0.01)
    assert math.degrees(motion.sweep_rad) == pytest.approx(12.0 * 15 / 16, abs=0.2)
    still = HeadPoses.from_arrays(np.array([0.0]), np.array([0.3]), np.array([0.1])).motion_over(2, 3)
    np.testing.assert_allclose(still.r_world_head, rotation_world_head(0.3, 0.1), atol=1e-12)
    assert still.sweep_rad == pytest.approx(0.0, abs=1e-6)


def test_power_weights_follow_the_loud_part_of_the_window():
    rng = np.random.default_rng(0)
    window = 0.01 * rng.standard_normal((4, 1600))
    window[:, 800:] *= 30.0  # speech in the second half only
    w = power_weights(window)
    assert w[:8].sum() < 0.01 * w[8:].sum()
    poses = HeadPoses.from_arrays(np.array([0.0, 0.1]), np.radians([0.0, 20.0]), np.zeros(2))
    motion = poses.motion_over(0.0, 0.1, w)
    az, _ = direction_to_base(0.0, None, motion.r_world_head)
    assert math.degrees(az) == pytest.approx(15.0, abs=0.5)  # where the head was while loud
    assert math.degrees(motion.sweep_rad) < 11.0  # only the loud half's sweep counts
    assert np.all(power_weights(np.ones((2, 160))) == 1.0)


def test_pose_history_order_duplicates_and_memory():
    poses = HeadPoses(keep_s=1.0)
    with pytest.raises(DataError, match="no head angles"):
        poses.angles_at(np.array([0.0]))
    for k in range(500):
        poses.add(0.01 * k, 0.001 * k, 0.0)
    poses.add(4.99, 0.499, 0.0)  # the same time again is ignored
    assert len(poses) < 200 and poses.span_s is not None and poses.span_s[1] == pytest.approx(4.99)
    pan, _ = poses.angles_at(np.array([4.5, 100.0]))
    assert pan == pytest.approx([0.45, 0.499])
    with pytest.raises(DataError, match="arrive after"):
        poses.add(1.0, 0.0, 0.0)
    with pytest.raises(DataError, match="not finite"):
        poses.add(6.0, math.nan, 0.0)


def test_encoder_logs_in_radians_degrees_and_the_engine_recording(tmp_path: Path):
    rad = tmp_path / "rad.csv"
    rad.write_text("t,pan,tilt,extra\n0.0,0.0,0.1,x\n1.0,0.5,0.1,y\n")
    deg = tmp_path / "deg.csv"
    deg.write_text(f"t_s,tilt_deg,pan_deg\n0,{math.degrees(0.1)},0\n1,{math.degrees(0.1)},"
                   f"{math.degrees(0.5)}\n")
    t = np.linspace(0.0, 2.0, 401)
    run = tmp_path / "run.csv"
    write_measurements({"pan": Measurement(t, 0 * t, 0.5 * t), "tilt": Measurement(t, 0 * t, 0.1 + 0 * t)},
                       run)
    for path in (rad, deg, run):
        pan, tilt = read_encoder_log(path).angles_at(np.array([0.5]))
        assert (pan[0], tilt[0]) == pytest.approx((0.25, 0.1)), path.name


@pytest.mark.parametrize(
    ("text", "fragment"),
    [("", "empty"), ("t,pan\n0,0\n", "lacks t, pan and tilt"), ("t,pan,tilt\n0,0,zero\n", "line 2"),
     ("t,pan,tilt\n", "no readings"), ("t,pan,tilt\n1,0,0\n0,0,0\n", "does not increase"),
     ("t,pan,tilt\n0,nan,0\n", "not finite")],
    ids=["empty", "no-tilt", "not-a-number", "header-only", "time-backwards", "nan"],
)
def test_bad_encoder_logs_name_the_file(tmp_path: Path, text: str, fragment: str):
    path = tmp_path / "enc.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=fragment) as err:
        read_encoder_log(path)
    assert "enc.csv" in str(err.value)
    with pytest.raises(DataError, match="not found"):
        read_encoder_log(tmp_path / "missing.csv")


# -- ground truth in a simulated room ------------------------------------------------------

ROOM = room.RoomSettings(rt60_s=0.3, snr_db=20.0, ism_order=6)


def head_array(name: str) -> MicArray:
    return dataclasses.replace(example_array(name), mount="head")


@pytest.mark.parametrize(
    ("name", "pan_deg", "tilt_deg", "talker_az_deg", "mouth_m"),
    [("square4_65mm", 50.0, 0.0, 10.0, 1.2), ("square4_65mm", -60.0, 20.0, -20.0, 1.2),
     ("cube8_50mm", -35.0, 15.0, 10.0, 1.7), ("seed_pairs", 30.0, 10.0, 45.0, 1.5)],
    ids=["square4-panned", "square4-panned-tilted", "cube8-panned-tilted", "seed-pairs"],
)
def test_head_mounted_estimates_plus_encoder_angles_give_the_base_direction(
        name: str, pan_deg: float, tilt_deg: float, talker_az_deg: float, mouth_m: float):
    array = head_array(name)
    placement = room.centre_placement(ROOM)
    speech = synthetic_speech(3.0, FS_HZ, seed=3)
    position = room.position_from_direction(placement, math.radians(talker_az_deg), 2.0, mouth_m)
    pan, tilt = math.radians(pan_deg), math.radians(tilt_deg)
    rec = simulate_head_mounted(ROOM, array, placement.position_m,
                                [room.static_talker(speech.samples, speech.active, position)],
                                np.zeros(1), np.array([pan]), np.array([tilt]))
    true_az, true_el = rec.directions(np.array([1.0]))[0, 0]
    pipeline = Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.5, 0.1, 1.5))
    result = locate_head_mounted(pipeline, rec.audio, HeadPoses.from_arrays(
        np.zeros(1), np.array([pan]), np.array([tilt])))
    frames = [f for f in result.frames if f.speech]
    assert len(frames) > 15
    errors = [angle_error_deg(f.azimuth_rad, true_az) for f in frames]
    assert np.median(errors) < 2.0 and np.percentile(errors, 90) < 4.0, errors
    if array.resolves_elevation:
        el_errors = [abs(math.degrees(f.elevation_rad - true_el)) for f in frames
                     if f.elevation_rad is not None]
        assert np.median(el_errors) < 3.0, el_errors
    else:
        assert all(f.elevation_rad is None for f in frames)
    assert angle_error_deg(result.track[-1].azimuth_rad, true_az) < 5.0
    # The head-frame estimates are elsewhere: the encoder angles did the work.
    raw = [f.azimuth_rad for f in pipeline.estimate_frames(rec.audio) if f.speech]
    assert angle_error_deg(float(np.median(raw)), true_az) > 20.0


MAP_HEAD_T_S = np.array([0.0, 1.9, 2.0, 4.0])  # the head steps from -50° to +20° between windows
MAP_HEAD_PAN_DEG = np.array([-50.0, -50.0, 20.0, 20.0])
MAP_HEAD_TILT_DEG = 10.0


def test_the_map_tracker_follows_a_talker_in_the_base_frame_while_the_head_turns():
    """A head-mounted square on a head tilted 10°, first at pan -50°, then turned to +20°: the
    talker (10° in the base frame) is first at +60°, then at -10° in the head frame. The map
    tracker, fed each window's map turned into the base frame, stays on her; streamed block by
    block it gives the same track."""
    array = head_array("square4_65mm")
    placement = room.centre_placement(ROOM)
    speech = synthetic_speech(4.0, FS_HZ, seed=11)
    position = room.position_from_direction(placement, math.radians(10.0), 2.0)
    tilt = math.radians(MAP_HEAD_TILT_DEG)
    rec = simulate_head_mounted(ROOM, array, placement.position_m,
                                [room.static_talker(speech.samples, speech.active, position)],
                                MAP_HEAD_T_S, np.radians(MAP_HEAD_PAN_DEG), np.full(4, tilt))
    true_az = float(rec.directions(np.array([1.0]))[0, 0, 0])
    t = np.arange(0.0, 4.005, 0.01)
    poses = HeadPoses.from_arrays(t, np.radians(np.interp(t, MAP_HEAD_T_S, MAP_HEAD_PAN_DEG)),
                                  np.full(t.size, tilt))
    meeting = MeetingSettings()

    def make() -> Pipeline:
        return Pipeline(array, FS_HZ, "srp_phat", meeting.windows, tracker="map",
                        map_tracking=meeting.map_tracking,
                        base_azimuth_range_rad=(-math.pi / 2, math.pi / 2))

    pipeline = make()
    assert pipeline.steer_azimuth_rad.size == 360 and pipeline.map_azimuth_rad.size == 181
    result = locate_head_mounted(pipeline, rec.audio, poses)
    talker = [p for p in result.track if p.shot == "talker"]
    assert len(talker) > 25
    assert angle_error_deg(result.track[-1].azimuth_rad, true_az) < 3.0
    after = [angle_error_deg(p.azimuth_rad, true_az) for p in talker if p.t_s > 2.5]
    assert after and max(after) < 4.0, after
    # Windows whose loud parts straddle the step (sweep > 10°) carry no map: the tracker skips them.
    across = [f for f in result.frames if f.end_s - meeting.windows.window_s < 2.0 < f.end_s]
    blank = [f.power_map is not None and bool(np.all(np.isnan(f.power_map))) for f in across]
    assert any(blank) and blank == [f.confidence == 0.0 for f in across]
    assert all(np.all(np.isfinite(f.power_map)) for f in result.frames
               if f.power_map is not None and f.confidence > 0)
    loc = StreamingLocator(make(), head_poses=poses)
    out = stream_blocks(loc, (rec.audio[:, i : i + 800] for i in range(0, rec.audio.shape[1], 800)))
    np.testing.assert_allclose([o.azimuth_rad for o in out],
                               [p.azimuth_rad if p.shot != "none" else math.nan for p in result.track],
                               atol=1e-9, equal_nan=True)


def test_the_map_tracker_on_a_head_tracks_the_base_view():
    """Without a base range the base grid is the array's view: the full circle, a circle."""
    array = head_array("square4_65mm")
    pipeline = Pipeline(array, FS_HZ, "srp_phat", tracker="map")
    assert pipeline.map_circular and pipeline.map_azimuth_rad.size == 360
    with pytest.raises(ConfigError, match="room-mounted"):
        Pipeline(example_array("square4_65mm"), FS_HZ, "srp_phat", tracker="map",
                 base_azimuth_range_rad=(-1.0, 1.0))
    with pytest.raises(DataError, match="head-frame map"):  # the batch run skipped the head angles
        Pipeline(array, FS_HZ, "srp_phat", tracker="map",
                 base_azimuth_range_rad=(-1.0, 1.0)).run(free_field(array, 0.3, duration_s=1.0))
