"""The effect catalogue: discovery, registration of a site's own effects, and what it refuses."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pytest

from tracker.errors import ConfigError
from tracker.plant.effects import (
    BUILTIN_EFFECTS,
    CATALOGUE,
    OPTIONAL_EFFECTS,
    Effect,
    FloatArray,
    Param,
    generic_effects,
    get_effect,
    load_effect_modules,
    optional_effects,
    register_effect,
    unregister_effect,
)
from tracker.plant.model import AxisModel

ROOT = Path(__file__).resolve().parents[3]
CABLE = ROOT / "examples" / "effects" / "cable_drag.py"


def _slope(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    return params["slope.k"] * np.asarray(theta, dtype=float)


def _effect(name: str = "slope", **changes: object) -> Effect:
    fields: dict[str, object] = {
        "name": name,
        "kind": "torque",
        "description": "a torque proportional to the angle",
        "params": (Param("k", "N·m/rad", 0.0, -1.0, 1.0, "slope"),),
        "signature": "residual torque rises with θ",
        "torque_nm": _slope,
    }
    fields.update(changes)
    return Effect(**fields)  # type: ignore[arg-type]


@pytest.fixture
def registered() -> Iterator[list[str]]:
    """Names registered by the test; removed afterwards so other tests see the built-ins only."""
    names: list[str] = []
    yield names
    for n in names:
        unregister_effect(n)


def test_built_ins_are_discovered_in_their_historical_order() -> None:
    assert tuple(CATALOGUE)[: len(BUILTIN_EFFECTS)] == (
        "inertia",
        "viscous",
        "coulomb",
        "coulomb_asymmetry",
        "viscous_asymmetry",
        "offset",
        "stiction",
        "gravity",
        "delay",
        "saturation",
        "ripple",
        "backlash",
        "compliance",
        "quantization",
    )
    assert generic_effects() == ()


def test_look_alikes_and_experiments_live_in_the_effect_files() -> None:
    assert get_effect("offset").look_alikes == ("coulomb_asymmetry", "gravity")
    assert "friction-id" in (get_effect("stiction").experiment or "")
    for e in CATALOGUE.values():
        assert all(a in CATALOGUE for a in e.look_alikes), e.name


def test_a_registered_effect_joins_the_catalogue_and_the_optional_effects(registered: list[str]) -> None:
    before = len(OPTIONAL_EFFECTS)
    effect = register_effect(_effect())
    registered.append("slope")
    assert CATALOGUE["slope"] is effect
    assert "slope" in OPTIONAL_EFFECTS and len(OPTIONAL_EFFECTS) == before + 1  # a live view
    assert optional_effects()[-1] == "slope" and generic_effects() == ("slope",)
    assert register_effect(effect) is effect  # the same object again: nothing happens
    model = AxisModel.for_axis("pan", ["slope"], {"slope.k": 0.2})
    assert model.params["slope.k"] == 0.2


def _speed_dependent(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    return params["slope.k"] * np.asarray(theta, dtype=float) + 0.01 * np.sign(omega)


def _switched_speed_term(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    # A viscous term its default of zero switches off: the probe must still see it.
    return params["slope.k"] * np.asarray(omega, dtype=float)


@pytest.mark.parametrize(
    ("effect", "message"),
    [
        (_effect("gravity"), "built-in"),
        (_effect("Bad-Name"), "lower case"),
        (_effect(params=(Param("k", "N·m/rad", 0.0, 1.0, -1.0, "slope"),)), "lower must be below upper"),
        (_effect(params=(Param("k", "N·m/rad", 2.0, -1.0, 1.0, "slope"),)), "outside"),
        (
            _effect(params=(Param("k", "1", 0.0, -1.0, 1.0, "a"), Param("k", "1", 0.0, -1.0, 1.0, "b"))),
            "two parameters",
        ),
        (_effect(torque_nm=_speed_dependent), "depends on the velocity"),
        (_effect(torque_nm=_switched_speed_term), "depends on the velocity"),
        (_effect(kind="input"), "kind 'input'"),
        (_effect(search={"width": (0.1, 0.2)}), "not one of its parameters"),
        (_effect(search={"k": (0.5, 2.0)}), "leaves its bounds"),
        (_effect(evidence="slope {slope:.3g}"), "evidence template"),
    ],
    ids=[
        "builtin-name",
        "bad-name",
        "bounds-reversed",
        "default-outside",
        "duplicate-param",
        "velocity-sign",
        "velocity-off-by-default",
        "not-a-torque",
        "search-unknown",
        "search-out-of-bounds",
        "evidence-template",
    ],
)
def test_a_malformed_effect_is_refused_with_a_clear_message(effect: Effect, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        register_effect(effect)
    assert effect.name not in CATALOGUE or effect.name in BUILTIN_EFFECTS


def test_a_second_effect_with_a_taken_name_is_refused(registered: list[str]) -> None:
    register_effect(_effect())
    registered.append("slope")
    with pytest.raises(ConfigError, match="already in the catalogue"):
        register_effect(_effect())


def _speed_term_above(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    k = params["slope.k"]
    return k * np.asarray(theta, dtype=float) + (0.1 * np.asarray(omega, dtype=float) if k > 50 else 0.0)


def test_model_creation_refuses_values_where_the_torque_depends_on_the_velocity(
    registered: list[str],
) -> None:
    wide = (Param("k", "N·m/rad", 0.0, -100.0, 100.0, "slope"),)
    register_effect(_effect(params=wide, torque_nm=_speed_term_above))
    registered.append("slope")
    AxisModel.for_axis("pan", ["slope"], {"slope.k": 1.0})
    with pytest.raises(ConfigError, match="depends on the velocity"):
        AxisModel.for_axis("pan", ["slope"], {"slope.k": 60.0})


def test_the_example_cable_drag_loads_from_its_file_once(registered: list[str]) -> None:
    assert load_effect_modules(str(CABLE)) == ("cable_drag",)
    registered.append("cable_drag")
    assert load_effect_modules(f" {CABLE} ,") == ("cable_drag",)  # loaded again: the same effect
    cable = get_effect("cable_drag")
    tau = cable.torque_nm(
        {"cable_drag.torque": 0.01, "cable_drag.stiffness": 0.02, "cable_drag.theta0": 0.5},
        np.array([0.5, 1.5]),
        np.zeros(2),
    )
    np.testing.assert_allclose(tau, [0.01, 0.03])
    assert cable.look_alikes == ("offset", "gravity") and cable.experiment


def _run_with_env(code: str, effects: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TRACKER_EFFECTS": effects, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=120
    )


def test_tracker_effects_names_plug_ins_loaded_with_the_catalogue() -> None:
    ok = _run_with_env("from tracker.plant.effects import CATALOGUE; print(list(CATALOGUE)[-1])", str(CABLE))
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == "cable_drag"


def test_a_plug_in_that_fails_to_load_is_one_error_line_from_the_command() -> None:
    code = "from tracker.cli import main; raise SystemExit(main(['model', '--help']))"
    bad = _run_with_env(code, "no_such.module")
    assert bad.returncode == 2
    assert bad.stderr.startswith("error: TRACKER_EFFECTS: cannot load effect module 'no_such.module'")
