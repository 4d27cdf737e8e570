"""Streaming localisation: block by block gives the batch pipeline's frames and track."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from tests.tracker.audio.conftest import FS_HZ, angle_error_deg, free_field
from tracker.audio import room
from tracker.audio.array import MicArray
from tracker.audio.head import HeadPoses, locate_head_mounted
from tracker.audio.head_room import simulate_head_mounted
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.sources import RoomSource, WavSource, write_wav
from tracker.audio.speech import synthetic_speech
from tracker.audio.stream import StreamingLocator, StreamTargetSource, stream_blocks
from tracker.errors import ConfigError, DataError

HALF_PLANE = {"azimuth_range_rad": (-np.pi / 2, np.pi / 2)}


def two_talkers(array: MicArray, az1: float, az2: float, seed: int = 1) -> np.ndarray:
    """Quiet noise, talker 1 for 3 s, noise, talker 2 for 3 s, noise: (n_mics, n)."""
    rng = np.random.default_rng(seed)
    gap = 0.001 * rng.standard_normal((array.n_mics, FS_HZ // 2))
    a = free_field(array, az1, duration_s=3.0, seed=seed)
    b = free_field(array, az2, duration_s=3.0, seed=seed + 1)
    return np.concatenate([gap, a, gap, b, gap], axis=1)


def pipeline(array: MicArray) -> Pipeline:
    return Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5),
                    localizer_options=HALF_PLANE)


@pytest.fixture(scope="module")
def recording(square4: MicArray) -> np.ndarray:
    return two_talkers(square4, math.radians(35.0), math.radians(-40.0))


@pytest.mark.parametrize("block", [160, 1234, 4000])
def test_streaming_matches_the_batch_pipeline(square4: MicArray, recording: np.ndarray,
                                              block: int) -> None:
    batch = pipeline(square4).run(recording)
    loc = StreamingLocator(pipeline(square4))
    loc.keep_frames = True
    out = stream_blocks(loc, (recording[:, i : i + block]
                              for i in range(0, recording.shape[1], block)))
    assert len(out) == len(batch.track) == len(loc.frames)
    assert [f.speech for f in loc.frames] == [f.speech for f in batch.frames]
    np.testing.assert_allclose([f.azimuth_rad for f in loc.frames],
                               [f.azimuth_rad for f in batch.frames], atol=1e-9)
    stream_az = np.array([t.azimuth_rad for t in out])
    batch_az = np.array([p.azimuth_rad if p.shot != "none" else math.nan for p in batch.track])
    np.testing.assert_allclose(stream_az, batch_az, atol=1e-6, equal_nan=True)
    assert [t.shot for t in out] == [p.shot for p in batch.track]
    # The buffer stays bounded (a few seconds), whatever the recording length.
    assert loc._buf.shape[1] < 6 * FS_HZ


def test_the_two_talkers_are_found_with_distinct_ids(square4: MicArray,
                                                     recording: np.ndarray) -> None:
    loc = StreamingLocator(pipeline(square4))
    out = stream_blocks(loc, blocks_of(recording))
    talking = [t for t in out if t.shot == "talker"]
    first = [t for t in talking if t.end_s < 3.5]
    last = [t for t in talking if t.end_s > 6.5]
    assert first and last
    assert abs(math.degrees(first[-1].azimuth_rad) - 35.0) < 5.0
    assert abs(math.degrees(last[-1].azimuth_rad) + 40.0) < 5.0
    assert first[-1].talker_id != last[-1].talker_id
    assert loc.latest == out[-1]
    # A target is never available before its window ended (causal), and lags it by the
    # speech detector's look-ahead at most.
    for t in out:
        assert t.end_s <= t.ready_s <= t.end_s + loc.lookahead / FS_HZ + 1e-9


def blocks_of(audio: np.ndarray) -> list[np.ndarray]:
    return [audio[:, i : i + 1600] for i in range(0, audio.shape[1], 1600)]


def test_a_wav_source_streams_like_the_array(square4: MicArray, recording: np.ndarray,
                                             tmp_path: Path) -> None:
    path = tmp_path / "meeting.wav"
    write_wav(path, FS_HZ, recording)
    src = WavSource(path)
    loc = StreamingLocator(pipeline(square4))
    out = stream_blocks(loc, src.blocks(0.1))
    batch = pipeline(square4).run(WavSource(path)._audio)
    batch_az = np.array([p.azimuth_rad if p.shot != "none" else math.nan for p in batch.track])
    np.testing.assert_allclose([t.azimuth_rad for t in out], batch_az, atol=1e-6, equal_nan=True)
    # 16-bit quantisation changes nothing that matters: same directions as the float audio.
    assert abs(math.degrees(out[-1].azimuth_rad) + 40.0) < 5.0


def test_a_room_source_streams(square4: MicArray, recording: np.ndarray) -> None:
    from tracker.audio.room import Recording

    fields = Recording.__dataclass_fields__
    kwargs = {"audio": recording, "fs_hz": FS_HZ}
    kwargs.update({k: None for k in fields if k not in kwargs})
    src = RoomSource(Recording(**kwargs))
    out = stream_blocks(StreamingLocator(pipeline(square4)), src.blocks(0.05))
    assert len(out) == len(pipeline(square4).run(recording).track)


def test_wrong_channel_count_or_nan_is_a_data_error(square4: MicArray) -> None:
    loc = StreamingLocator(pipeline(square4))
    with pytest.raises(DataError, match="2 channel"):
        loc.push(np.zeros((2, 100)))
    bad = np.zeros((square4.n_mics, 100))
    bad[0, 5] = np.nan
    with pytest.raises(DataError, match="NaN"):
        loc.push(bad)


def test_target_source_reports_the_latest_and_goes_stale(square4: MicArray,
                                                          recording: np.ndarray) -> None:
    loc = StreamingLocator(pipeline(square4))
    out = stream_blocks(loc, blocks_of(recording))
    src = StreamTargetSource(stale_s=1.0)
    assert src.target_at(0.0) is None
    src.offer(out[0], 0.0)  # before the first shot: nothing to say
    assert src.target_at(0.1) is None
    src.offer(out[-1], 5.0)
    t = src.target_at(5.5)
    assert t is not None and t.pan_rad == pytest.approx(out[-1].azimuth_rad)
    assert t.tilt_rad == 0.0 and t.talker is not None
    assert src.engine_t_s == 5.5
    assert src.target_at(6.5) is None  # nothing new for more than stale_s


# -- a head-mounted array: estimates are turned into the base frame with the head's angles --

TALKER_BASE_DEG = 35.0
HEAD_T_S = np.array([0.0, 2.0, 2.6, 5.0])  # the head turns 40° toward the talker at 67°/s
HEAD_PAN_RAD = np.radians([0.0, 0.0, 40.0, 40.0])


def head_pipeline(array: MicArray, tracker: str = "kalman") -> Pipeline:
    """The map tracker keeps talkers in the front half of the base frame (a camera on a wall)."""
    if tracker == "map":
        return Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5), tracker="map",
                        base_azimuth_range_rad=(-np.pi / 2, np.pi / 2))
    return Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5))


def encoder_poses(keep_s: float = 30.0) -> HeadPoses:
    """The head's angles as the engine publishes them: every 10 ms."""
    poses = HeadPoses(keep_s)
    for t in np.arange(0.0, 5.0, 0.01):
        poses.add(float(t), float(np.interp(t, HEAD_T_S, HEAD_PAN_RAD)), 0.0)
    return poses


@pytest.fixture(scope="module")
def head_array(square4: MicArray) -> MicArray:
    return dataclasses.replace(square4, mount="head")


@pytest.fixture(scope="module")
def turning_head(head_array: MicArray) -> np.ndarray:
    """5 s of one talker at 35° (base frame) while the head-mounted array turns 0° -> 40°."""
    settings = room.RoomSettings(rt60_s=0.3, snr_db=20.0, ism_order=6)
    placement = room.centre_placement(settings)
    speech = synthetic_speech(5.0, FS_HZ, seed=5)
    position = room.position_from_direction(placement, math.radians(TALKER_BASE_DEG), 2.0)
    rec = simulate_head_mounted(settings, head_array, placement.position_m,
                                [room.static_talker(speech.samples, speech.active, position)],
                                HEAD_T_S, HEAD_PAN_RAD, np.zeros(4))
    truth = rec.directions(np.array([0.0]))[0, 0, 0]
    assert math.degrees(truth) == pytest.approx(TALKER_BASE_DEG, abs=0.5)
    return rec.audio


def test_a_turning_head_keeps_the_talker_in_the_base_frame(head_array: MicArray,
                                                           turning_head: np.ndarray) -> None:
    loc = StreamingLocator(head_pipeline(head_array), head_poses=encoder_poses())
    loc.keep_frames = True
    out = stream_blocks(loc, blocks_of(turning_head))
    talker = math.radians(TALKER_BASE_DEG)
    # The camera target stays on the one talker, before, during and after the head's turn.
    shots = [t for t in out if t.shot == "talker"]
    assert len(shots) > 30 and {t.talker_id for t in shots} == {0}
    assert max(angle_error_deg(t.azimuth_rad, talker) for t in shots) < 5.0
    # Per-window estimates in the base frame, both before and after the turn.
    for lo, hi in ((0.0, 2.0), (2.9, 5.0)):
        frames = [f for f in loc.frames if f.speech and f.confidence > 0 and lo < f.t_s < hi]
        errors = [angle_error_deg(f.azimuth_rad, talker) for f in frames]
        assert len(frames) > 8 and np.median(errors) < 2.5, (lo, errors)
    # Windows recorded while the head swept more than 10° carry no direction.
    turning = [f for f in loc.frames if 2.2 < f.end_s < 2.6]
    assert turning and all(f.confidence == 0.0 for f in turning)
    # The 1.5 s refining windows that span the turn are dropped; they return after it.
    spanning = [f for f in loc.frames if f.speech and 2.4 < f.end_s < 3.7]
    assert spanning and all(f.fine_azimuth_rad is None for f in spanning)
    assert any(f.fine_azimuth_rad is not None for f in loc.frames if f.speech and f.end_s > 4.2)
    # The same audio taken as a room-mounted array's: after the turn it is 40° off.
    fixed = StreamingLocator(head_pipeline(dataclasses.replace(head_array, mount="room")))
    fixed.keep_frames = True
    stream_blocks(fixed, blocks_of(turning_head))
    after = [f.azimuth_rad for f in fixed.frames if f.speech and f.t_s > 2.9]
    assert angle_error_deg(float(np.median(after)), talker - math.radians(40.0)) < 3.0


@pytest.mark.parametrize(("block", "tracker"), [(160, "kalman"), (4000, "kalman"), (160, "map")],
                         ids=["kalman-160", "kalman-4000", "map-160"])
def test_streaming_a_head_mounted_array_matches_the_batch(head_array: MicArray,
                                                          turning_head: np.ndarray,
                                                          block: int, tracker: str) -> None:
    batch = locate_head_mounted(head_pipeline(head_array, tracker), turning_head, encoder_poses())
    if tracker == "map":  # each window's map turned into the base frame: the track stays on her
        talker = [p for p in batch.track if p.shot == "talker"]
        assert len(talker) > 30 and max(
            angle_error_deg(p.azimuth_rad, math.radians(TALKER_BASE_DEG)) for p in talker) < 3.0
    loc = StreamingLocator(head_pipeline(head_array, tracker), head_poses=encoder_poses(keep_s=3.0))
    loc.keep_frames = True
    out = stream_blocks(loc, (turning_head[:, i : i + block]
                              for i in range(0, turning_head.shape[1], block)))
    np.testing.assert_allclose([f.azimuth_rad for f in loc.frames],
                               [f.azimuth_rad for f in batch.frames], atol=1e-9)
    assert [f.confidence for f in loc.frames] == pytest.approx([f.confidence for f in batch.frames])
    for streamed, batched in zip(loc.frames, batch.frames, strict=True):
        if batched.power_map is not None:
            assert streamed.power_map is not None and streamed.power_map.shape == (181,)
            np.testing.assert_allclose(streamed.power_map, batched.power_map, atol=1e-9)
    batch_az = np.array([p.azimuth_rad if p.shot != "none" else math.nan for p in batch.track])
    np.testing.assert_allclose([t.azimuth_rad for t in out], batch_az, atol=1e-6, equal_nan=True)


def test_push_carries_the_head_angles_of_each_block(head_array: MicArray) -> None:
    pan = math.radians(50.0)
    audio = free_field(head_array, math.radians(20.0) - pan, duration_s=3.0, seed=4)
    loc = StreamingLocator(head_pipeline(head_array))
    out = []
    for block in blocks_of(audio):
        out.extend(loc.push(block, head_pan_rad=pan, head_tilt_rad=0.0))
    out.extend(loc.finish())
    assert out[-1].shot == "talker"
    assert angle_error_deg(out[-1].azimuth_rad, math.radians(20.0)) < 3.0


def test_head_angles_and_mounts_must_agree(square4: MicArray, head_array: MicArray) -> None:
    with pytest.raises(ConfigError, match="room-mounted"):
        StreamingLocator(pipeline(square4), head_poses=HeadPoses())
    with pytest.raises(ConfigError, match="room-mounted"):
        StreamingLocator(pipeline(square4)).push(np.zeros((4, 160)), head_pan_rad=0.1,
                                                 head_tilt_rad=0.0)
    with pytest.raises(ConfigError, match="both"):
        StreamingLocator(head_pipeline(head_array)).push(np.zeros((4, 160)), head_pan_rad=0.1)
    blind = StreamingLocator(head_pipeline(head_array))
    with pytest.raises(DataError, match="no head angles"):
        stream_blocks(blind, blocks_of(free_field(head_array, 0.3, duration_s=1.0)))


def test_the_tilt_follows_the_talker_when_the_array_resolves_elevation() -> None:
    from tests.tracker.audio.conftest import example_array

    cube = example_array("cube8_50mm")
    audio = free_field(cube, math.radians(30.0), math.radians(15.0), duration_s=3.0, seed=9)
    out = stream_blocks(StreamingLocator(head_pipeline(cube)), blocks_of(audio))
    src = StreamTargetSource()
    src.offer(out[-1], 0.0)
    target = src.target_at(0.0)
    assert target is not None and out[-1].shot == "talker"
    assert math.degrees(target.pan_rad) == pytest.approx(30.0, abs=3.0)
    assert math.degrees(target.tilt_rad) == pytest.approx(15.0, abs=3.0)
