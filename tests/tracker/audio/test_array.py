"""Array geometry: example files load, bad files fail clearly, delays and frames are right."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.audio.array import (
    MicArray,
    array_from_dict,
    head_to_world,
    load_array,
    rotation_world_head,
    unit_vector,
)
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


def test_mount_defaults_to_the_room_and_the_seed_layout_rides_on_the_head(tmp_path):
    path = tmp_path / "a.json"
    path.write_text(json.dumps({"mics": [[0.03, 0, 0], [-0.03, 0, 0]]}))
    assert load_array(path).mount == "room" and not load_array(path).head_mounted
    path.write_text(json.dumps({"mics": [[0.03, 0, 0], [-0.03, 0, 0]], "mount": "head"}))
    assert load_array(path).head_mounted
    # The seed added the encoder angle to each estimate (chapter 5): its pairs rode on the head.
    assert load_array(ARRAYS_DIR / "seed_pairs.json").mount == "head"
    assert load_array(ARRAYS_DIR / "square4_65mm.json").mount == "room"


@pytest.mark.parametrize(
    ("mount", "shown"),
    [("floor", '"floor"'), ("Head", '"Head"'), (1, "1"), (None, "null"), (["head"], '["head"]')],
    ids=["unknown-word", "wrong-case", "number", "null", "list"],
)
def test_a_bad_mount_names_the_file_and_the_value(tmp_path, mount, shown):
    path = tmp_path / "bad_mount.json"
    path.write_text(json.dumps({"mics": [[0.03, 0, 0], [-0.03, 0, 0]], "mount": mount}))
    with pytest.raises(ConfigError) as err:
        load_array(path)
    message = str(err.value)
    assert "bad_mount.json" in message and shown in message
    assert '"room", "wall", "table", "ceiling", "head"' in message


def test_a_misspelt_key_is_refused_not_ignored(tmp_path):
    path = tmp_path / "typo.json"
    path.write_text(json.dumps({"mics": [[0.03, 0, 0], [-0.03, 0, 0]], "mounting": "head"}))
    with pytest.raises(ConfigError, match="typo.json.*'mounting'"):
        load_array(path)


def test_mic_array_is_frozen_and_checks_its_mount():
    array = MicArray(np.array([[0.03, 0, 0], [-0.03, 0, 0]]), name="x", mount="head")
    with pytest.raises(dataclasses.FrozenInstanceError):
        array.mount = "room"  # type: ignore[misc]
    with pytest.raises(ConfigError, match="x: mount is 'shelf'"):
        MicArray(np.array([[0.03, 0, 0], [-0.03, 0, 0]]), name="x", mount="shelf")


@settings(max_examples=100, deadline=None)
@given(pan=st.floats(-4.0, 4.0), tilt=st.floats(-1.5, 1.5))
def test_head_rotation_is_a_proper_rotation_and_vectorises(pan, tilt):
    r = rotation_world_head(pan, tilt)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    stacked = rotation_world_head(np.array([pan, 0.0]), np.array([tilt, 0.0]))
    np.testing.assert_allclose(stacked[0], r, atol=1e-15)
    np.testing.assert_allclose(stacked[1], np.eye(3), atol=1e-15)
