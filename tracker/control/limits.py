"""Soft limits (pan ±90°, tilt ±45°) that no target, gain or command can pass.

Two lines of defence:

1. :func:`clamp_target` keeps every target inside the limits less ``target_margin_rad``
   (the shaper in :mod:`tracker.control.trajectory` also brakes in time for them);
2. the last line runs after any controller. :func:`guard_command` (rigid model) predicts
   where the axis would stop if it braked now, from the *observed* velocity, the command
   latency and the deceleration the motor can surely deliver (the axis's rated braking
   envelope and its own measured full-command acceleration, :mod:`tracker.control.envelope`;
   never more than the controller's model says), and overrides the command with a
   full brake when that stop point reaches the guard line (``guard_margin_rad`` inside the
   limit); at rest near the line it forbids outward commands, and past the line it pushes back
   at full command. For a model with a belt, :mod:`tracker.control.belt_guard` replaces it.

Which last line runs depends on what the design model knows.

**Rigid model** (:func:`guard_command`). Assumes that unmodelled torques (gravity, offset,
ripple...) and a lower amplifier clip leave at least ``BRAKE_FRACTION`` of the rated braking
torque (or of what the axis showed at its last full command), that the command delay is within
``GUARD_LATENCY_S`` (less one sample), and that the transmission is stiff: the encoder is on
the motor, so backlash within the margin (tested to 0.23°) is covered. A belt the model does
not know is covered only through the site's ``guard_margin_rad``
(``EngineConfig.guard_margin_rad``): :func:`unknown_belt_margin_rad` gives the margin for a belt
known to be at least f Hz stiff and damped at least ζ (the load's lead over the braking motor).
The guard stops the motor from the encoder and its *reach* (:func:`guard_command_held`: the
fastest recent outward speed, so a belt swinging the motor slower for a moment cannot hide the
load's speed), checks both positions before either stop point, and the full-command
measurement counts only three agreeing second differences (:mod:`tracker.control.envelope`).
Measured (bench/bench_limits_belt.py, belts f_min–300 Hz, ζ ≥ 0.1, f_min 20/30/50 Hz): 0 of
8000 runs past, the closest 1.6° inside (3.7° for f_min 30 Hz); the property test covers
f_min = 30 Hz. Lightly damped belts (ζ 0.02–0.1): the load stayed inside in 8000 runs, but the
encoder passes (up to 10.8°, the guard's delayed full brakes pump the motor through the belt).
Soft belts (≲ 30 Hz) need margins of tens of degrees: fit the belt instead.

**Model with the belt** (``compliance``, e.g. fitted by the workbench and confirmed by the
axis's recent motion, :mod:`tracker.model_check`; the belt guard in
:mod:`tracker.control.belt_guard`): a two-mass observer, a model-predicted trigger and a
latching backup keep the *load* inside lines moved in by the guard margin plus twice the belt's
twist under ``BELT_LOAD_TORQUE_NM`` and the model's gravity (:func:`belt_guard_lines`).
Assumptions: the belt's frequency and damping as modelled (measured: ±5 % frequency error and
×2 damping error absorbed, ±10 % let 3 runs in 1800 pass by up to 4.0°); motor-side hidden
effects as for the rigid guard (offset, friction asymmetry, stiction, ripple, backlash, delay
≤ ``belt_guard_design.HIDDEN_DELAY_S``, amplifier clip ≥ ``belt_guard_design.BACKUP_LIMIT_V``); load-side
torques the model does not know ≤ ``BELT_LOAD_TORQUE_NM`` (their twist is invisible to the
motor encoder: that is the physics the margin pays for); the axis starts at rest inside the
lines. Under them neither a random search (1200 runs) nor the property test found a run past;
what is proven is the backup's linear robustness (:func:`belt_guard_design.backup_spectral_radius`) and, for
the linear model, the prediction's end (a Lyapunov ellipsoid); the rest is measured, not a
proof (docs/control.md, "Soft limits"). The motor side (encoder) is not kept inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.plant.params import get_preset

# Fraction of the nominal 10 V torque (less Coulomb friction's help) counted on for braking.
BRAKE_FRACTION = 0.5
TARGET_MARGIN_RAD = math.radians(0.5)
GUARD_MARGIN_RAD = math.radians(0.25)
# Targets stay at least this far inside the rigid guard's line, however far a site margin moves
# it in: normal motion then stops short of the line instead of riding the guard's full brake.
TARGET_INSIDE_GUARD_RAD = TARGET_MARGIN_RAD - GUARD_MARGIN_RAD
# Latency between deciding to brake and the torque acting: one sample plus slack for delay.
GUARD_LATENCY_S = 0.004
# The guard's own observer bandwidth: fixed, so that no gain setting can blind the last line.
GUARD_OBSERVER_HZ = 40.0
# Belt guard: the largest load-side torque the model may not know (unmodelled gravity, cable
# drag; N·m). The encoder is on the motor: such a torque twists the belt by τ/k unseen, and a
# step of it swings the load up to twice that, so the guard line moves in by 2τ/k.
BELT_LOAD_TORQUE_NM = 0.03
# The damping ratio an unknown belt is assumed to have at least (unknown_belt_margin_rad).
UNKNOWN_BELT_MIN_DAMPING = 0.1


@dataclass(frozen=True, slots=True)
class SoftLimits:
    """Soft limits of one axis (rad) and the guard's margins."""

    lower_rad: float
    upper_rad: float
    target_margin_rad: float = TARGET_MARGIN_RAD
    guard_margin_rad: float = GUARD_MARGIN_RAD

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lower_rad) and math.isfinite(self.upper_rad)):
            raise ConfigError(f"soft limits must be finite, got [{self.lower_rad!r}, {self.upper_rad!r}]")
        for name in ("target_margin_rad", "guard_margin_rad"):
            margin = getattr(self, name)
            if not (math.isfinite(margin) and margin >= 0.0):
                raise ConfigError(f"SoftLimits.{name} must be a finite angle >= 0 rad, got {margin!r}")
        if self.upper_rad - self.lower_rad <= 2.0 * self.guard_margin_rad:
            raise ConfigError(
                f"soft limits [{self.lower_rad:g}, {self.upper_rad:g}] rad leave no room inside the "
                f"{self.guard_margin_rad:g} rad guard margin"
            )
        if self.upper_rad - self.lower_rad <= 2.0 * self.target_line_margin_rad:
            raise ConfigError(
                f"soft limits [{self.lower_rad:g}, {self.upper_rad:g}] rad leave no room inside the "
                f"{self.target_line_margin_rad:g} rad margin"
            )

    @property
    def target_line_margin_rad(self) -> float:
        """How far inside the limits the rigid guard's controller clamps targets: the target
        margin, and at least ``TARGET_INSIDE_GUARD_RAD`` inside the guard line."""
        return max(self.target_margin_rad, self.guard_margin_rad + TARGET_INSIDE_GUARD_RAD)

    @classmethod
    def for_axis(cls, axis: str, guard_margin_rad: float = GUARD_MARGIN_RAD) -> SoftLimits:
        """The seed's limits: pan ±90°, tilt ±45° (Table 1.1), with a site's guard margin."""
        lim = get_preset(axis).soft_limit_rad
        return cls(-lim, lim, guard_margin_rad=guard_margin_rad)

    def check_target(self, axis: str, angle_rad: float) -> float:
        """Return ``angle_rad`` or raise ConfigError naming the limit it breaks."""
        if not math.isfinite(angle_rad):
            raise ConfigError(f"{axis} target {angle_rad!r} is not a finite angle")
        if angle_rad < self.lower_rad or angle_rad > self.upper_rad:
            raise ConfigError(
                f"{axis} target {math.degrees(angle_rad):.2f}° is outside the soft limit "
                f"[{math.degrees(self.lower_rad):.1f}°, {math.degrees(self.upper_rad):.1f}°]"
            )
        return angle_rad


def belt_guard_lines(model: AxisModel, limits: SoftLimits) -> tuple[float, float]:
    """The load angles (rad) the belt guard keeps the load within: the limits less the guard
    margin and twice the belt's twist under ``BELT_LOAD_TORQUE_NM`` plus the model's gravity
    amplitude (torques on the load the motor-side encoder cannot tell from one on the motor;
    the belt guard's observer lumps them with the motor's, so a known gravity costs margin too)."""
    load_torque_nm = BELT_LOAD_TORQUE_NM + abs(model.params.get("gravity.torque", 0.0))
    twist = 2.0 * belt_twist_rad(model, load_torque_nm)
    lo = limits.lower_rad + limits.guard_margin_rad + twist
    hi = limits.upper_rad - limits.guard_margin_rad - twist
    if hi - lo <= 0.0:
        raise ConfigError(
            f"the belt of {model.params['compliance.frequency']:g} Hz needs {twist:.3g} rad of twist margin "
            f"(twice its twist under {load_torque_nm:g} N·m): no room is left inside the soft limits "
            f"[{limits.lower_rad:g}, {limits.upper_rad:g}] rad"
        )
    return lo, hi


def belt_twist_rad(model: AxisModel, torque_nm: float) -> float:
    """Static twist (rad) of ``model``'s belt under ``torque_nm``: τ / k, k = (2πf)²·Jm·Jl/J."""
    p = model.params
    j, frac = p["inertia.J"], p["inertia.motor_fraction"]
    k = (2.0 * math.pi * p["compliance.frequency"]) ** 2 * j * frac * (1.0 - frac)
    return torque_nm / k


def unknown_belt_margin_rad(
    model: AxisModel,
    min_frequency_hz: float,
    min_damping: float = UNKNOWN_BELT_MIN_DAMPING,
    u_max_v: float = 10.0,
) -> float:
    """Guard margin (rad) for a rig whose belt the model does not know, only that it is at least
    ``min_frequency_hz`` stiff and damped at least ``min_damping`` (ratio ζ): the load's lead
    over the encoder when the full brake's torque reaches the load as a step, (1 + e^(−ζπ/√(1−ζ²)))
    times the static twist K·u_max·(Jl/J)/k under it (a second-order belt overshoots its static
    twist by that factor; ζ = 0 gives twice the twist).

    Why this twist: the rigid guard stops the *motor* (encoder) at its line, counting on the
    encoder's angle and the largest outward speed it saw lately (the reach,
    :func:`guard_command_held`); while the full brake holds the motor back, the belt carries
    the load ahead of it by the transmitted torque over the stiffness, Jl/J of the brake's
    torque (the load decelerates with the axis). ``model`` is the (rigid) design model; its
    ``inertia.motor_fraction`` sets the split.
    """
    if not (math.isfinite(min_frequency_hz) and min_frequency_hz > 0.0):
        raise ConfigError(
            f"belt frequency bound must be a positive frequency in Hz, got {min_frequency_hz!r}"
        )
    if not (math.isfinite(min_damping) and 0.0 <= min_damping < 1.0):
        raise ConfigError(f"belt damping bound must be a ratio in [0, 1), got {min_damping!r}")
    belt = model.with_effect("compliance", {"compliance.frequency": min_frequency_hz})
    frac = model.params["inertia.motor_fraction"]
    overshoot = math.exp(-min_damping * math.pi / math.sqrt(1.0 - min_damping**2))
    return (1.0 + overshoot) * belt_twist_rad(belt, model.gain_nm_per_v * u_max_v * (1.0 - frac))


def brake_decel_rad_s2(gain_nm_per_v: float, inertia_kg_m2: float, u_max_v: float = 10.0) -> float:
    """The deceleration (rad/s²) the guard counts on: BRAKE_FRACTION of K·u_max/J."""
    return BRAKE_FRACTION * gain_nm_per_v * u_max_v / inertia_kg_m2


@njit(cache=True, inline="always")
def clamp_target(target_rad: float, lo_rad: float, hi_rad: float, margin_rad: float) -> float:
    """The target clamped into [lo + margin, hi − margin]; NaN becomes the centre."""
    a = lo_rad + margin_rad
    b = hi_rad - margin_rad
    if target_rad != target_rad:
        return 0.5 * (a + b)
    if target_rad < a:
        return a
    if target_rad > b:
        return b
    return target_rad


@njit(cache=True, inline="always")
def _stop_point(theta: float, omega: float, accel_now: float, decel: float, latency: float) -> float:
    """How far (rad, ≥ θ) an axis moving at ω ≥ 0 gets if it keeps accelerating at ``accel_now``
    for ``latency`` s and then brakes at ``decel``."""
    v = omega + accel_now * latency
    if v < 0.0:
        v = 0.0
    return theta + omega * latency + 0.5 * accel_now * latency * latency + v * v / (2.0 * decel)


@njit(cache=True)
def guard_command(
    u_v: float,
    theta_a: float,
    omega_a: float,
    theta_b: float,
    omega_b: float,
    lo_rad: float,
    hi_rad: float,
    guard_margin_rad: float,
    decel_rad_s2: float,
    latency_s: float,
    u_max_v: float,
    accel_per_v: float,
) -> float:
    """:func:`guard_command_held` with the current velocities as the reach (nothing held)."""
    reach_hi = max(omega_a, omega_b, 0.0)
    reach_lo = min(omega_a, omega_b, 0.0)
    return guard_command_held(
        u_v, theta_a, omega_a, theta_b, omega_b, reach_hi, reach_lo, lo_rad, hi_rad,
        guard_margin_rad, decel_rad_s2, latency_s, u_max_v, accel_per_v,
    )


@njit(cache=True, inline="always")
def held_speed(held_rad_s: float, speed_rad_s: float, decay_rad_s: float) -> float:
    """max(speed, held − decay): an outward speed (≥ 0) that falls no faster than ``decay`` per
    sample, for the guard's reach (:func:`guard_command_held`)."""
    return max(speed_rad_s, held_rad_s - decay_rad_s, 0.0)


@njit(cache=True)
def guard_command_held(
    u_v: float,
    theta_a: float,
    omega_a: float,
    theta_b: float,
    omega_b: float,
    reach_hi_rad_s: float,
    reach_lo_rad_s: float,
    lo_rad: float,
    hi_rad: float,
    guard_margin_rad: float,
    decel_rad_s2: float,
    latency_s: float,
    u_max_v: float,
    accel_per_v: float,
) -> float:
    """The last line: ``u_v`` unless the axis could run past a soft limit; then a full brake.

    Two estimates of angle and velocity (a: the guard's observer, b: the encoder and its
    one-sample difference) are combined pessimistically on each side. The stop point assumes
    the command keeps accelerating the axis (``accel_per_v``·u, rad/s² per V) for ``latency_s``
    before the brake acts. Returns volts.

    Past a line the axis is pushed back in, whatever either stop point says: both are checked
    only once both positions are inside. (When the high side was checked first, an axis past
    the *low* line whose estimates disagreed in sign — a belt swinging the motor — was braked
    against the high side, i.e. pushed further out, sample after sample: an unknown 30–60 Hz
    belt walked the load 287° past; docs/control.md, "Soft limits".) If both stop points cross
    their lines (the two velocity estimates point opposite ways), the side whose stop point is
    further past its line is braked against.
    """
    if u_v != u_v:  # NaN from absurd gains: stop pushing
        u_v = 0.0
    elif u_v > u_max_v:  # the amplifier clips anyway; absurd gains must not blind the estimate
        u_v = u_max_v
    elif u_v < -u_max_v:
        u_v = -u_max_v
    hi = hi_rad - guard_margin_rad
    lo = lo_rad + guard_margin_rad
    push = accel_per_v * u_v
    th_hi = max(theta_a, theta_b)
    om_hi = max(omega_a, omega_b, 0.0)
    th_lo = min(theta_a, theta_b)
    om_lo = min(omega_a, omega_b, 0.0)
    if th_hi >= hi:  # over the line (e.g. crept there under gravity): push back in
        return -u_max_v
    if th_lo <= lo:
        return u_max_v
    over_hi = _stop_point(th_hi, max(reach_hi_rad_s, om_hi), max(push, 0.0), decel_rad_s2, latency_s) - hi
    over_lo = lo + _stop_point(-th_lo, -min(reach_lo_rad_s, om_lo), max(-push, 0.0), decel_rad_s2, latency_s)
    if over_hi >= 0.0 and om_hi > 0.0 and not (over_lo > over_hi and om_lo < 0.0):
        return -u_max_v
    if over_lo >= 0.0 and om_lo < 0.0:
        return u_max_v
    if over_hi >= 0.0 and u_v > 0.0:  # at rest near the line: no outward command
        return 0.0
    if over_lo >= 0.0 and u_v < 0.0:
        return 0.0
    return u_v
