"""What the log's own slow load disturbance can make of a torque effect.

A load disturbance that wanders slowly (an Ornstein–Uhlenbeck torque, a cable's drag that
changes over seconds) does not average out over the samples where the axis moves: over a log
with a few moves, its mean there wanders by about σ_d·√(2τ/T_moving), and the torque regression
reads that mean as a bias torque (or as a Coulomb asymmetry, or as gravity over a short travel).
The regression's F-test cannot see this: its effective sample size is read from the residual's
autocorrelation, which the fast part of the residual (the encoder's differentiated quantization)
dominates. An independent generator's clean cascade log (1 kHz, σ_d 1.5 mN·m, τ 67 ms, moving
27 % of 20 s) had a disturbance averaging −0.75 mN·m over its moving samples, and the workbench
named a bias torque of −0.83 mN·m.

So the spectrum of the disturbance is read from the log itself (the k-step residual, as the
residual test does: :func:`tracker.workbench.compare.floor.disturbance_amplitude`, which removes
what a catalogue torque error could explain first, so a real bias is not taken for disturbance),
and each candidate torque is set against the spread that disturbance gives its projection on the
samples the regression used: Var(β) = (2/n²)·Σ_f A(f)²·|W(f)|², W the DFT of the projection's
weights. A torque the disturbance alone reaches within :data:`MIN_OVER_WANDER` of these standard
deviations is "significant but small" (see :data:`MIN_OVER_WANDER`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tracker.plant.effects import get_effect
from tracker.plant.model import AxisModel
from tracker.workbench.compare.floor import SensorNoise, disturbance_amplitude, disturbance_rms_nm
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import Signals
from tracker.workbench.measurements.states import estimate_states, with_load_observer

FloatArray = NDArray[np.float64]

# Effects whose torque the disturbance reading removes before it reads the disturbance (the
# catalogue columns of :func:`tracker.workbench.compare.floor.disturbance_amplitude`): a true one
# is not taken for disturbance, so its size can be set against the disturbance's wander. (A
# ripple or an effect of one's own would be read partly as disturbance: not judged here.)
JUDGED_EFFECTS = ("offset", "coulomb_asymmetry", "viscous_asymmetry", "gravity")
# A torque effect must stand this many standard deviations of the disturbance's own projection
# clear of zero. Four look-alike shapes are judged on every log, and the spectrum near zero rests
# on a few bins of a 20-30 s log (an OU disturbance's wander over one clean log's moves read
# 0.17 mN·m where 300 draws of the true process give 0.21): 5, as for a discovery. The clean log
# above stood 4.8 of them clear (3.9 of the true process's); true biases, Coulomb asymmetries and
# gravity torques of an independent generator's four seeds 6.9-220.
MIN_OVER_WANDER = 5.0


@dataclass(frozen=True, slots=True)
class SlowDisturbance:
    """The log's load disturbance as a Fourier amplitude (rfft bins of the log's length, N·m)."""

    amplitude_nm: FloatArray
    n: int
    use: NDArray[np.int64]  # the samples the torque regression used (moving, away from rests)

    @classmethod
    def read(cls, meas: Measurement, model: AxisModel, sig: Signals, horizon_s: float) -> SlowDisturbance:
        """Read it from the k-step residual of ``model`` (the model the candidates are judged
        against), as the residual test does."""
        est = with_load_observer(estimate_states(meas, model), model, meas)
        amp = disturbance_amplitude(meas, model, est, horizon_s, SensorNoise.from_log(meas.theta_rad))
        return cls(np.asarray(amp, dtype=float), meas.n, np.asarray(sig.use, dtype=np.int64))

    @property
    def rms_nm(self) -> float:
        return disturbance_rms_nm(self.amplitude_nm, self.n)

    def wander(self, column: FloatArray) -> float:
        """Standard deviation of the disturbance's least-squares projection on ``column`` (a
        torque shape on the used samples, shape (len(use),)), in units of that column: what the
        disturbance alone makes of an effect of that shape (1.0 = the effect's own size)."""
        c = np.asarray(column, dtype=float)
        cc = float(c @ c)
        if cc <= 0.0 or not np.any(self.amplitude_nm > 0):
            return 0.0
        w = np.zeros(self.n)
        w[self.use] = c / cc
        spec = np.fft.rfft(w)
        a2 = self.amplitude_nm**2
        var = 2.0 / self.n**2 * float(np.sum(a2[1:] * np.abs(spec[1:]) ** 2))
        return math.sqrt(max(var, 0.0))


# The torque terms a candidate of :data:`JUDGED_EFFECTS` changes when it is added: its own, and
# the base friction it is refitted with (a Coulomb asymmetry splits Coulomb friction: added to a
# model it moves Coulomb too, and what it adds is a bias per direction, not its one-sided term).
TORQUE_TERMS = ("coulomb", "viscous", *JUDGED_EFFECTS)


def model_torque(model: AxisModel, sig: Signals) -> FloatArray:
    """The friction and catalogue torques of position and velocity ``model`` has, on the
    regression's used samples, N·m."""
    theta, omega = sig.theta_rad[sig.use], sig.omega_rad_s[sig.use]
    total = np.zeros(theta.size)
    for name in TORQUE_TERMS:
        if name in ("coulomb", "viscous") or model.has(name):
            total += np.asarray(get_effect(name).torque_nm(model.params, theta, omega), dtype=float)
    return total


def within_disturbance(
    effect: str, model: AxisModel, base: AxisModel, sig: Signals, slow: SlowDisturbance
) -> str | None:
    """Why ``effect`` (``model`` is ``base`` with it added) adds no larger a torque than the log's
    slow disturbance makes of a torque of that shape, or None (also for effects not judged here)."""
    if effect not in JUDGED_EFFECTS:
        return None
    added = model_torque(model, sig) - model_torque(base, sig)
    if not np.any(added != 0.0):
        return None
    spread = slow.wander(added)
    if spread <= 0.0 or 1.0 / spread >= MIN_OVER_WANDER:
        return None
    size = float(np.sqrt(np.mean(added**2)))
    return (
        f"the torque it adds ({size:.2g} N·m RMS where the axis moves) is {1.0 / spread:.1f} standard "
        f"deviations of what the log's own slow load disturbance ({slow.rms_nm:.2g} N·m RMS, read from "
        f"the k-step residual) makes of a torque of that shape over these moves ({size * spread:.2g} "
        f"N·m); a missing effect needs {MIN_OVER_WANDER:.0f}"
    )


__all__ = ["JUDGED_EFFECTS", "MIN_OVER_WANDER", "SlowDisturbance", "model_torque", "within_disturbance"]
