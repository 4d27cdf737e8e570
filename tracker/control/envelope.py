"""The braking envelope the soft-limit guard counts on, whatever the controller's model says.

The rigid guard (:func:`tracker.control.limits.guard_command`) needs two numbers: the
deceleration a full-command brake surely gives (a *lower* bound, a_brake) and the acceleration
per volt the current command may add while the brake is on its way (an *upper* bound). Taking
them from the controller's design model made the last line only as good as that model: a model
fitted to the log of a lighter axis (inertia ×0.2) promised 2.5× the braking the rig has, and
the load went 43° past the limit (docs/control.md, "Soft limits"). Three sources now, and the
guard takes the most pessimistic of them:

1. **the rating** of the axis hardware (:meth:`BrakingEnvelope.for_axis`: the seed's gear,
   torque constant, amplifier and inertia, Appendix A; a site whose payload is heavier says so
   with ``EngineConfig.envelopes``): ``brake_fraction``·K·u_max/J, the same half of the full
   torque the rigid guard always assumed (hidden torques and a lower clip leave at least that);
2. **the design model**, which can only make the guard more cautious (a heavier model lowers
   a_brake; a lighter one cannot raise it above the rating);
3. **the axis's own motion at full command**, measured on line (:func:`measure_full_command`):
   while the applied command stays at ±u_max (from the command latency on) and the axis moves,
   the second difference of the encoder over two windows of ``MEASURE_WINDOW_S`` is the
   acceleration the rig really gave, taken every window; once three in a row agree within
   ``MEASURE_AGREEMENT`` (a belt the model does not know swings the motor and scatters them),
   ``MEASURED_FRACTION`` of the smallest caps a_brake. A full *acceleration* counts as well as
   a brake: friction helps a brake and hinders a start, so an axis brakes at least as hard as
   it starts (up to torques that depend on the direction or the angle, which the fraction pays
   for: gravity 0.12 N·m on the seed's pan is 16 % of its full torque each way). A rig heavier
   than its rating is thus found while it first runs up to speed at full command, before the
   brake that needs it (measured: a brake-only version found it during that brake, too late).

The push during the latency uses the largest K/J of the rating and the model. The guard's own
observer is designed on the rating (:meth:`BrakingEnvelope.observer_model`), so no model can
blind it either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.control.limits import BRAKE_FRACTION
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.plant.params import get_preset
from tracker.units import AMPLIFIER_LIMIT_V

FloatArray = NDArray[np.float64]

# The measured acceleration is counted at this fraction: torques that depend on the direction
# or vary along the travel (gravity, offset, ripple) may brake less than the rig started or
# braked where it was measured.
MEASURED_FRACTION = 0.6
# Length of each of the two windows whose second difference measures the deceleration: at
# 100 rad/s² it spans 13.5 encoder counts (7 % resolution). Short windows let a belt's swing
# scatter single measurements more, which the agreement of three (below) rejects: on a synthetic
# swing of 0.5–3° at 30–120 Hz the counted value never fell below 0.84× the truth (with 10 ms
# windows 0.53×, and the first count came 20 ms later, too late for some heavier rigs).
MEASURE_WINDOW_S = 0.005
# A measurement counts only if the axis moved this fast over the last window (rad/s): an axis
# held by stiction or stopping inside the window would understate what the torque does.
MEASURE_MIN_SPEED_RAD_S = 0.5
# The smallest deceleration a measurement may set, as a fraction of the rating (a guard that
# believes in no braking at all would refuse every outward move; below this the axis is broken).
MEASURED_FLOOR_FRACTION = 0.02

# Three consecutive measurements (second differences one window apart) must agree within this
# share of the largest before the smallest counts: a rigid axis at full command accelerates
# steadily (up to quantization), while a belt the model does not know swings the motor about
# the load and its second differences with it. Measured on 30–60 Hz belts (10 ms windows, one
# measurement counted), single ones ranged from −1600 to +1100 rad/s² on a tilt that
# accelerates at 460, set the counted braking to its floor in 1 run in 20, and the guard then
# braked at every swing (docs/control.md, "Soft limits").
MEASURE_AGREEMENT = 0.25

# Measurement state (offsets in the controller's state slice): the sign of the full command
# being timed (0: none), samples since it began, encoder at the last three window marks
# (oldest first: E_Y0, E_Y1, E_Y2), the counted acceleration along the command (0: none yet),
# and the two previous marks' unconfirmed ones (newest first; 0: none).
E_DIR, E_N, E_Y0, E_Y1, E_DECEL, E_Y2, E_PREV, E_PREV2 = 0, 1, 2, 3, 4, 5, 6, 7
N_ES = 8


@dataclass(frozen=True, slots=True)
class BrakingEnvelope:
    """The rated capability of one axis: gain K (N·m/V), the largest inertia J (kg·m²) it
    carries, its viscous friction (N·m·s/rad, for the guard's observer) and the share of the
    full torque counted on for braking."""

    gain_nm_per_v: float
    inertia_kg_m2: float
    viscous_nm_s_per_rad: float = 0.0
    brake_fraction: float = BRAKE_FRACTION

    def __post_init__(self) -> None:
        for name in ("gain_nm_per_v", "inertia_kg_m2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"BrakingEnvelope.{name} must be a positive number, got {value!r}")
        if not (math.isfinite(self.viscous_nm_s_per_rad) and self.viscous_nm_s_per_rad >= 0.0):
            raise ConfigError(
                f"BrakingEnvelope.viscous_nm_s_per_rad must be >= 0, got {self.viscous_nm_s_per_rad!r}"
            )
        if not (0.0 < self.brake_fraction <= 1.0):
            raise ConfigError(
                f"BrakingEnvelope.brake_fraction must be in (0, 1], got {self.brake_fraction!r}"
            )

    @classmethod
    def for_axis(cls, axis: str, inertia_factor: float = 1.0) -> BrakingEnvelope:
        """The seed hardware's rating of ``axis`` (Appendix A); ``inertia_factor`` for a site
        whose payload is heavier than the seed's (the inertia it may carry, ≥ the seed's)."""
        preset = get_preset(axis)
        return cls(preset.gain_nm_per_v, preset.inertia_kg_m2 * inertia_factor, preset.viscous_nm_s_per_rad)

    @classmethod
    def of_model(cls, model: AxisModel) -> BrakingEnvelope:
        """The envelope a model implies (trusting it: for design studies on a known twin)."""
        p = model.params
        return cls(model.gain_nm_per_v, p["inertia.J"], p["viscous.b"])

    def brake_decel_rad_s2(self, u_max_v: float = AMPLIFIER_LIMIT_V) -> float:
        """The deceleration (rad/s²) a full brake surely gives: brake_fraction·K·u_max/J."""
        return self.brake_fraction * self.gain_nm_per_v * u_max_v / self.inertia_kg_m2

    def push_accel_per_v(self) -> float:
        """Acceleration per volt (rad/s² per V) of the rated axis, K/J."""
        return self.gain_nm_per_v / self.inertia_kg_m2

    def observer_model(self) -> AxisModel:
        """A rigid model of the rated axis, for the guard's own observer."""
        return AxisModel.create(
            self.gain_nm_per_v,
            {"inertia.J": self.inertia_kg_m2, "viscous.b": self.viscous_nm_s_per_rad, "coulomb.torque": 0.0},
        )


@dataclass(frozen=True, slots=True)
class GuardFigures:
    """What the rigid guard is packed with: the braking it counts on (rad/s²) and the push per
    volt it allows for during the latency (rad/s² per V)."""

    brake_decel_rad_s2: float
    push_accel_per_v: float


def guard_figures(
    envelope: BrakingEnvelope, model: AxisModel, u_max_v: float = AMPLIFIER_LIMIT_V
) -> GuardFigures:
    """The rating's and the model's figures, the most pessimistic of each (the measured
    acceleration then caps the braking at run time, :func:`counted_decel`)."""
    from_model = BrakingEnvelope.of_model(model)
    return GuardFigures(
        min(envelope.brake_decel_rad_s2(u_max_v), from_model.brake_decel_rad_s2(u_max_v)),
        max(envelope.push_accel_per_v(), from_model.push_accel_per_v()),
    )


@njit(cache=True, inline="always")
def measure_full_command(
    es: FloatArray, y_rad: float, u_v: float, u_max_v: float, settle: float, window: float, dt: float
) -> None:
    """Time full commands and measure the acceleration they give; ``es`` (N_ES,) is updated.

    ``u_v`` is the command applied this sample. From ``settle`` samples after it reached ±u_max
    (the command latency), the encoder ``y_rad`` is marked every ``window`` samples; from the
    third mark on, each mark gives the acceleration along the command over the last two
    windows, sign(u)·(y₂ − 2y₁ + y₀)/(window·dt)², if the axis still moved faster than
    MEASURE_MIN_SPEED_RAD_S over the last window. When the last three of them agree
    within MEASURE_AGREEMENT, the smallest is stored as the measurement. Any smaller command
    ends the timing.
    """
    direction = 0.0
    if u_v >= u_max_v:
        direction = 1.0
    elif u_v <= -u_max_v:
        direction = -1.0
    if direction == 0.0 or direction != es[0]:  # es[E_DIR]: a new full command, or none
        es[0] = direction
        es[1] = 0.0
        es[6] = 0.0  # es[E_PREV], es[E_PREV2]
        es[7] = 0.0
        return
    n = es[1] + 1.0  # es[E_N]
    es[1] = n
    m = n - settle
    if m < 0.0 or m % window != 0.0:
        return
    es[2] = es[3]  # a window mark: E_Y0 ← E_Y1 ← E_Y2 ← y
    es[3] = es[5]
    es[5] = y_rad
    if m < 2.0 * window:
        return
    span = window * dt
    acc = 0.0
    if abs(y_rad - es[3]) > MEASURE_MIN_SPEED_RAD_S * span:
        acc = direction * (y_rad - 2.0 * es[3] + es[2]) / (span * span)
    p1, p2 = es[6], es[7]  # es[E_PREV], es[E_PREV2]
    if acc != 0.0 and p1 != 0.0 and p2 != 0.0:
        top = max(abs(acc), abs(p1), abs(p2))
        if max(acc, p1, p2) - min(acc, p1, p2) <= MEASURE_AGREEMENT * top:
            es[4] = min(acc, p1, p2)  # es[E_DECEL]
    es[7] = p1
    es[6] = acc


@njit(cache=True, inline="always")
def counted_decel(rated_decel: float, es: FloatArray) -> float:
    """The deceleration (rad/s²) the guard counts on now: the packed (rated/model) bound, capped
    by MEASURED_FRACTION of the latest measurement, never below MEASURED_FLOOR_FRACTION of it."""
    measured = float(es[4])
    if measured == 0.0:
        return rated_decel
    decel = min(rated_decel, MEASURED_FRACTION * measured)
    return max(decel, MEASURED_FLOOR_FRACTION * rated_decel)
