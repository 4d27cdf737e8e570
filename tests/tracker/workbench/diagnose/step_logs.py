"""Open-loop voltage-step logs of the independent truth generator's axis (its own integrator
and Karnopp stick-slip), for the tests of what starts and rests say (rests, start lags), and
the torque regression's base model they are judged against."""

from __future__ import annotations

from typing import Any

import numpy as np

from tests.truthgen.axis import TrueAxis
from tests.truthgen.excitation import disturbance
from tests.truthgen.presets import GAIN_NM_PER_V
from tests.truthgen.run import replay
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.judgement import with_values
from tracker.workbench.diagnose.screening import Structure, TorqueDesign, model_params
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import Regression, Signals, prepare_signals

RATE_HZ = 1000.0
COULOMB_NM = 0.055
PARAMS = {
    "inertia.J": 0.0015,
    "viscous.b": 0.0005,
    "coulomb.torque": COULOMB_NM,
    "inertia.motor_fraction": 0.15,
    "quantization.step": 2 * np.pi / 4096,
}


def step_log(
    rng: np.random.Generator,
    u_v: np.ndarray,
    hidden: dict[str, Any],
    disturbance_nm: float,
    name: str,
) -> Measurement:
    """20 s of ``u_v`` on the true axis with the ``hidden`` effects' parameters (their names'
    first parts are the hidden effects), a slow disturbance of ``disturbance_nm`` drawn from
    ``rng`` after the steps, and a one-sample latency."""
    n = u_v.size
    dist = disturbance(rng, n, 1.0 / RATE_HZ, disturbance_nm, 2.0)
    effects = sorted({k.split(".")[0] for k in hidden})
    axis = TrueAxis(GAIN_NM_PER_V, {**PARAMS, **hidden}, effects, "karnopp", {})
    log = replay(axis, u_v, RATE_HZ, latency_samples=1, dist=dist)
    return Measurement(log.t, log.u, log.theta, name)


def base_model() -> AxisModel:
    return AxisModel.for_axis("pan", gain_nm_per_v=GAIN_NM_PER_V)


def regression_base(meas: Measurement) -> tuple[Signals, Regression, AxisModel, float]:
    """The log's signals, the torque regression, the base model with its values and the
    sliding Coulomb torque it measured (as the diagnosis judges rests and starts)."""
    model = base_model()
    sig = prepare_signals(meas)
    reg = TorqueDesign(sig, model.gain_nm_per_v, model.params["inertia.motor_fraction"]).fit(
        Structure.of(model)
    )
    values, _ = model_params(model, Structure.of(model), reg)
    return sig, reg, with_values(model, values), float(values["coulomb.torque"])
