"""The camera-operator policy: bounds with meanings, and both trackers taking a new one mid-run."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tests.tracker.audio.conftest import FS_HZ, free_field
from tracker.audio.array import MicArray
from tracker.audio.map_tracking import MapTracker, MapTrackerSettings
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.policy import POLICY_FIELDS, CameraPolicy
from tracker.audio.stream import StreamingLocator
from tracker.audio.tracking import TalkerTracker, TrackerSettings
from tracker.errors import ConfigError, OutOfRange

A_RAD, B_RAD = math.radians(-30.0), math.radians(30.0)
GRID_RAD = np.deg2rad(np.arange(-90.0, 91.0, 1.0))


def test_the_defaults_are_the_trackers_own() -> None:
    assert CameraPolicy.of(TrackerSettings()) == CameraPolicy() == CameraPolicy.of(MapTrackerSettings())
    assert {f.name for f in POLICY_FIELDS} == {f.name for f in dataclasses.fields(CameraPolicy)}
    assert all(f.meaning and f.low < f.high for f in POLICY_FIELDS)


@pytest.mark.parametrize(
    ("changes", "words"),
    [({"min_hold_s": 31.0}, ["min_hold_s=31.0", "0-30 s", "stays on the new talker"]),
     ({"reaction_time_s": -1}, ["reaction_time_s=-1", "0.05-3 s"]),
     ({"deadband_rad": 1.0}, ["deadband_rad=1.0", "0-30°"]),
     ({"wide_after_switches": 2.5}, ["wide_after_switches=2.5", "whole numbers 2-50"]),
     ({"lead_s": float("nan")}, ["lead_s=nan"]),
     ({"lead_s": True}, ["lead_s=True"])],
    ids=["hold", "reaction", "deadband", "count", "nan", "bool"],
)
def test_a_value_out_of_range_is_refused_naming_field_range_and_meaning(
        changes: dict[str, object], words: list[str]) -> None:
    with pytest.raises(OutOfRange) as err:
        CameraPolicy().replaced(changes)
    for word in words:
        assert word in str(err.value)
    assert err.value.name == next(iter(changes))


def test_an_unknown_field_is_refused_listing_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="min_hold.*settings: reaction_time_s, min_hold_s"):
        CameraPolicy().replaced({"min_hold": 3.0})


def scripted_talkers() -> list[tuple[float, float]]:
    """Talker A at -30° for 3 s, B at +30° cuts in for 1 s, A again until 12 s; a frame per 0.1 s."""
    return [(round(0.1 * k, 3), B_RAD if 30 <= k < 40 else A_RAD) for k in range(120)]


def back_on_a_s(tracker: TalkerTracker | MapTracker, new_policy_at_s: float | None,
                policy: CameraPolicy) -> float:
    """When the shot returns to A after B's cut, ``tracker`` taking ``policy`` at the given time."""
    shots = []
    for t_s, az in scripted_talkers():
        if new_policy_at_s is not None and abs(t_s - new_policy_at_s) < 1e-9:
            tracker.settings = policy.apply(tracker.settings)  # type: ignore[assignment]
        az += 0.01 * math.sin(7.0 * t_s)
        if isinstance(tracker, TalkerTracker):
            point = tracker.step(t_s, az, None, 1.0, True)
        else:
            bump = np.exp(-0.5 * ((GRID_RAD - az) / math.radians(6.0)) ** 2)
            point = tracker.step(t_s, bump, None, True, 1.0)
        shots.append((t_s, point.azimuth_rad))
    on_b = next(t for t, az in shots if az > 0.0)
    return next(t for t, az in shots if t > on_b and az < 0.0)


@pytest.mark.parametrize("kind", ["kalman", "map"])
def test_a_longer_minimum_hold_set_mid_run_keeps_the_shot_longer(kind: str) -> None:
    """The same tracker instance, its policy changed after the cut to B (no restart): with the
    default 2 s hold the shot returns to A about 2 s after the cut; with 5 s, 3 s later."""

    def run(new_policy_at_s: float | None) -> float:
        tracker = TalkerTracker() if kind == "kalman" else MapTracker(GRID_RAD)
        return back_on_a_s(tracker, new_policy_at_s, CameraPolicy(min_hold_s=5.0))

    default, longer = run(None), run(3.5)
    assert 5.0 <= default <= 5.5
    assert longer - default == pytest.approx(3.0, abs=0.15)


def test_the_streaming_locator_takes_a_policy_between_frames(square4: MicArray) -> None:
    """set_policy from another thread lands at the next frame, in both trackers' settings and
    the pipeline's (a locator built from it later uses it too); the talker is kept."""
    pipeline = Pipeline(square4, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5), tracker="map",
                        localizer_options={"azimuth_range_rad": (-math.pi / 2, math.pi / 2)})
    loc = StreamingLocator(pipeline)
    audio = free_field(square4, math.radians(40.0), duration_s=3.0)
    loc.push(audio[:, : 2 * FS_HZ])
    talker_before = loc.latest
    assert talker_before is not None and talker_before.shot == "talker"
    policy = CameraPolicy(min_hold_s=7.5, deadband_rad=math.radians(10.0), lead_s=0.0)
    loc.set_policy(policy)
    assert loc.policy == policy
    assert loc._map_tracker is not None and loc._map_tracker.settings.min_hold_s == 2.0
    loc.push(audio[:, 2 * FS_HZ :])
    assert loc._map_tracker.settings.min_hold_s == 7.5 and loc._tracker.settings.lead_s == 0.0
    assert CameraPolicy.of(pipeline.map_tracking) == policy == CameraPolicy.of(pipeline.tracking)
    after = loc.latest
    assert after is not None and after.talker_id == talker_before.talker_id
