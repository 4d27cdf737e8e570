"""Array geometry: example files load, bad files fail clearly, delays and frames are right."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tracker.audio.array import array_from_dict, head_to_world, load_array, unit_vector
from tracker.errors import ConfigError

from .conftest import ARRAYS_DIR


@pytest.mark.parametrize("path", sorted(ARRAYS_DIR.glob("*.json")), ids=lambda p: p.stem)
def test_example_arrays_load(path):
    array = load_array(path)
    assert 2 <= array.n_mics <= 8
    assert len(array.pairs) == array.n_mics * (array.n_mics - 1) // 2
    assert np.all(array.max_lag_s > 0) and np.all(array.max_lag_s < 0.3 / 343.0 * 2)


def test_seed_layout_has_one_pair_per_axis():
    seed = load_array(ARRAYS_DIR / "seed_pairs.json")
    assert seed.resolves_elevation and not seed.resolves_front_back


@pytest.mark.parametrize(
    "data, fragment",
    [
        ({"mic": []}, "expected a JSON object"),
        ({"mics": [[0, 0, 0]]}, "at least 2"),
        ({"mics": [[0, 0], [1, 0]]}, "triples"),
        ({"mics": [[0, 0, 0], [0, 0, 0.0001]]}, "closer than 1 mm"),
        ({"mics": [[0, 0, 0], [50, 0, 0]]}, "metres"),
    ],
    ids=["no-mics-key", "one-mic", "pairs-not-triples", "coincident", "millimetres"],
)
def test_bad_geometry_is_a_config_error(data, fragment):
    with pytest.raises(ConfigError, match=fragment):
        array_from_dict(data)


def test_unreadable_array_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ConfigError, match="bad.json"):
        load_array(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_array(tmp_path / "missing.json")


def test_delay_sign_left_mic_hears_a_left_source_first():
    array = array_from_dict({"mics": [[0, 0.1, 0], [0, -0.1, 0]]})
    # Source at +90° (left): mic 0 (left) first, so mic 1 lags by 0.2 m / c.
    tau = array.delays_s(unit_vector(np.pi / 2, 0.0))
    assert tau[0] == pytest.approx(0.2 / 343.0)


def test_head_to_world_adds_pan_and_handles_tilt():
    d = head_to_world(np.deg2rad(10), 0.0, np.deg2rad(30), 0.0)
    assert np.rad2deg(d.azimuth_rad) == pytest.approx(40.0)
    up = head_to_world(0.0, 0.0, 0.0, np.deg2rad(20))
    assert np.rad2deg(up.elevation_rad) == pytest.approx(20.0)
    # A direction on the head's axis stays on the camera axis whatever the pan/tilt.
    d = head_to_world(0.0, 0.0, np.deg2rad(-70), np.deg2rad(25))
    assert np.rad2deg([d.azimuth_rad, d.elevation_rad]) == pytest.approx([-70.0, 25.0])


def test_array_json_roundtrip(tmp_path):
    path = tmp_path / "a.json"
    path.write_text(json.dumps({"mics": [[0.03, 0, 0], [-0.03, 0, 0], [0, 0.03, 0]]}))
    assert load_array(path).n_mics == 3
