"""Model versions: each added effect is a refitted version, the history keeps every fit."""

import json
from pathlib import Path

import pytest

from tracker.errors import ConfigError, DataError
from tracker.plant.model import AxisModel
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.versions import VersionStore, add_effect, first_version, remove_effect


def test_adding_the_missing_effects_makes_the_error_fall_and_is_kept(tmp_path: Path) -> None:
    true = AxisModel.for_axis(
        "pan",
        ["quantization", "offset", "gravity"],
        {"offset.torque": 0.01, "gravity.torque": 0.05, "gravity.phase": 0.3},
    )
    meas = closed_loop_log(true, duration_s=15.0, seed=6)
    h = first_version(meas, AxisModel.for_axis("pan"))
    h = add_effect(h, meas, "gravity")
    h = add_effect(h, meas, "offset")
    fits = [v.fit_percent_increment for v in h.versions]
    assert [v.number for v in h.versions] == [1, 2, 3]
    assert [v.change for v in h.versions] == ["base", "+gravity", "+offset"]
    assert fits[0] < fits[1] < fits[2]
    assert h.latest.model.params["gravity.torque"] == pytest.approx(0.05, rel=0.1)
    with pytest.raises(ConfigError, match="already has"):
        add_effect(h, meas, "offset")

    store = VersionStore(tmp_path)
    store.save("pan-rig", h)
    back = VersionStore(tmp_path).load("pan-rig")
    assert back.fit_history() == h.fit_history()
    assert dict(back.latest.model.params) == dict(h.latest.model.params)
    assert store.names() == ["pan-rig"]
    assert not list(tmp_path.glob("*.part"))

    h4 = remove_effect(h, meas, "offset")
    assert h4.latest.change == "-offset" and not h4.latest.model.has("offset")


def test_store_rejects_bad_names_and_corrupt_files(tmp_path: Path) -> None:
    store = VersionStore(tmp_path)
    with pytest.raises(ConfigError, match="name"):
        store.load("../etc/passwd")
    (tmp_path / "broken.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(DataError, match="broken.json"):
        store.load("broken")
    (tmp_path / "odd.json").write_text(json.dumps({"versions": [{"number": 1}]}), encoding="utf-8")
    with pytest.raises(DataError, match="version 1"):
        store.load("odd")
    assert VersionStore().load("nothing").versions == ()


def test_stored_asymmetric_friction_survives_a_round_trip(tmp_path: Path) -> None:
    """Regression: rebuilding a stored model through create(base_params=...) reset the
    negative-direction Coulomb torque to the positive one."""
    from tracker.workbench.versions import ModelVersion, VersionHistory

    model = AxisModel.for_axis("pan", ["coulomb_asymmetry"], {"coulomb_asymmetry.negative": 0.08})
    v = ModelVersion(1, model, "base+coulomb_asymmetry", 99.0, 95.0, 0.01)
    store = VersionStore(tmp_path)
    store.save("asym", VersionHistory((v,)))
    back = store.load("asym").latest.model
    assert back.params["coulomb_asymmetry.negative"] == 0.08
    assert back.params["coulomb.torque"] == model.params["coulomb.torque"]
