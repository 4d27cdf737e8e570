"""Camera profiles: every shipped profile loads; counts, frames and speed codes convert both ways."""

import math

import pytest

from tracker.drivers.camera_profiles import get_profile, profile_from_mapping, profile_names
from tracker.errors import ConfigError


@pytest.mark.parametrize("name", ["generic", "sony_srg", "sony_evi_d70", "ptzoptics"])
def test_shipped_profiles_load_with_full_speed_tables(name: str) -> None:
    p = get_profile(name)
    assert len(p.speeds_rad_s["pan"]) == 0x18 and len(p.speeds_rad_s["tilt"]) == 0x14
    assert p.range_rad["pan"][0] < -math.pi / 2 and p.range_rad["pan"][1] > math.pi / 2
    assert name in profile_names()


def test_console_pan_left_is_visca_pan_right_negative() -> None:
    p = get_profile("sony_evi_d70")  # 0.075 deg per count (Sony EVI-D70 manual)
    assert p.to_counts("pan", math.radians(30.0)) == -400
    assert p.to_counts("tilt", math.radians(-7.5)) == -100
    assert p.to_rad("pan", -400) == pytest.approx(math.radians(30.0))


def test_speed_code_rounds_down_to_the_table() -> None:
    p = get_profile("sony_srg")  # EVI-D100 table: code 0x13 = 100 deg/s, 0x14 = 125 deg/s
    assert p.speed_code("pan", math.radians(110.0)) == 0x13
    assert p.speed_code("pan", math.radians(125.0)) == 0x14
    assert p.speed_code("pan", math.radians(0.1)) == 1
    assert p.speed_code("pan", 100.0) == 0x18


def test_a_bad_profile_is_refused_naming_the_key() -> None:
    spec = {
        "deg_per_count": 0.07, "pan_range_deg": [-170, 170], "tilt_range_deg": [-30, 90],
        "pan_speeds_deg_s": [1.0] * 24, "tilt_speeds_deg_s": list(range(1, 21)), "accel_deg_s2": 100,
        "backlash_deg": 0.0, "zoom_max": 16384, "zoom_counts_s": 1000, "pan_sign": -1, "tilt_sign": 1,
    }
    with pytest.raises(ConfigError, match="pan_speeds_deg_s must rise"):
        profile_from_mapping("bad", spec)
    with pytest.raises(ConfigError, match="unknown camera profile 'nikon'"):
        get_profile("nikon")
