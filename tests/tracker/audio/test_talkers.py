"""The talkers a stream has followed: where each is, when each last spoke, who speaks now."""

from __future__ import annotations

import math

import numpy as np

from tests.tracker.audio.conftest import FS_HZ, angle_error_deg
from tests.tracker.audio.test_stream import pipeline, two_talkers
from tracker.audio.array import MicArray
from tracker.audio.stream import StreamingLocator


def test_each_talker_is_listed_with_bearing_last_speech_and_who_speaks(square4: MicArray) -> None:
    """Talker 1 at 35° (0.5-3.5 s), talker 2 at -40° (4-7 s): while 2 talks, both are listed,
    2 speaking; after the end silence, nobody is."""
    audio = two_talkers(square4, math.radians(35.0), math.radians(-40.0))
    loc = StreamingLocator(pipeline(square4))
    assert loc.talkers() == []
    loc.push(audio[:, : int(6.0 * FS_HZ)])
    talkers = loc.talkers()
    assert len(talkers) == 2
    first, second = talkers
    assert angle_error_deg(first.azimuth_rad, math.radians(35.0)) < 3.0
    assert angle_error_deg(second.azimuth_rad, math.radians(-40.0)) < 3.0
    assert (first.speaking, second.speaking) == (False, True)
    assert 3.0 < first.last_spoken_s < 3.6 and 1.5 < first.speaking_s < 3.1
    assert first.first_s < 1.0 < 4.0 < second.first_s < 4.8
    latest = loc.latest
    assert latest is not None and latest.talker_id == second.talker_id == 1
    quiet = 0.001 * np.random.default_rng(9).standard_normal((4, FS_HZ))
    loc.push(np.concatenate([audio[:, int(6.0 * FS_HZ) :], quiet], axis=1))
    loc.finish()
    end = loc.talkers()
    assert not any(t.speaking for t in end)  # 1.5 s of quiet noise at the end
    assert 6.5 < end[1].last_spoken_s < 7.1 and end[0].last_spoken_s == first.last_spoken_s
    assert np.isclose(end[0].speaking_s, first.speaking_s)
