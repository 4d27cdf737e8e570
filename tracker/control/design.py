"""Controller design from the axis model with python-control: the seed's lead, ours, margins.

The loop is analysed where the seed analysed it (ch. 4): the linearised plant
(K/J)/(s² + (b/J)s) (Coulomb dropped), discretised with a zero-order hold at Ts = 1 ms,
times the *feedback part* of the controller as the discrete LTI system from the encoder angle
to the command (for "observer_pd_ff": observer + PID, with the reference at zero; the
feedforward does not change the loop). ``delay_samples`` adds z^-d of computation delay.

Registry: ``CONTROLLERS`` maps a name to a design function ``(model, **options) -> gains``;
:func:`design_controller` designs and reports margins. :func:`check_gains` is the safety
check used by the engine (and the console's ``PUT /axes/{axis}/gains``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from tracker.control.gains import ControllerGains, LeadGains, ObserverPdGains
from tracker.control.observer import design_observer
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel

FloatArray = NDArray[np.float64]
TS_S = 1e-3
# The seed's lead (eqs. 4.4–4.5, Appendix D): the tilt gain 141 and the poles 0.9 (tilt) and
# 0.87 (pan) survive in the report; the zeros and the pan gain were lost. We reconstruct them
# (see seed_lead_gains) from the reported phase margins, pan 9.5°, tilt 7.3° (Figure 4.1 order).
SEED_TILT_GAIN_V_PER_RAD = 141.0
SEED_POLES = {"pan": 0.87, "tilt": 0.9}
SEED_PHASE_MARGIN_DEG = {"pan": 9.5, "tilt": 7.3}


@dataclass(frozen=True, slots=True)
class DesignReport:
    """Margins of the linearised loop L(z) = C(z)·P(z)·z^-d.

    ``gain_margin_db`` is inf when the phase never crosses −180° above the crossover;
    ``stable`` is from the closed-loop poles (all inside the unit circle), not the margins.
    """

    phase_margin_deg: float
    gain_margin_db: float
    crossover_hz: float
    stable: bool
    max_pole_radius: float
    delay_samples: int
    min_phase_margin_deg: float = 0.0

    @property
    def ok(self) -> bool:
        """Stable and at least the required phase margin."""
        return self.stable and self.phase_margin_deg >= self.min_phase_margin_deg

    def describe(self) -> str:
        """One line for error messages and logs."""
        return (
            f"phase margin {self.phase_margin_deg:.1f}° (required {self.min_phase_margin_deg:.1f}°), "
            f"gain margin {self.gain_margin_db:.1f} dB, crossover {self.crossover_hz:.2f} Hz, "
            f"{'stable' if self.stable else 'UNSTABLE'} (max |pole| {self.max_pole_radius:.4f})"
        )


@dataclass(frozen=True, slots=True)
class ControllerDesign:
    """A named controller designed on ``model``: its gains and the loop's margins."""

    name: str
    gains: ControllerGains
    report: DesignReport
    report_with_delay: DesignReport


def plant_zoh(model: AxisModel, dt_s: float = TS_S) -> control.TransferFunction:
    """The linearised plant discretised with a zero-order hold."""
    return control.c2d(model.linearised_tf(), dt_s, method="zoh")


def feedback_controller(model: AxisModel, gains: ControllerGains, dt_s: float = TS_S) -> control.StateSpace:
    """The feedback part as a discrete LTI system y → −u (so that the loop is C·P, negative feedback)."""
    if isinstance(gains, LeadGains):
        g = gains.gain_v_per_rad
        return control.tf2ss(control.tf([g, -g * gains.zero], [1.0, -gains.pole], dt_s))
    obs = design_observer(model, gains.observer_bandwidth_hz, dt_s)
    a, b, c, ell = obs.a, obs.b.reshape(-1, 1), obs.c.reshape(1, -1), obs.l.reshape(-1, 1)
    m = np.eye(3) - ell @ c  # x̂ = M x⁻ + L y
    g_dist = gains.disturbance_comp / model.gain_nm_per_v
    g_fb = np.array([[gains.kp_v_per_rad, gains.kd_v_s_per_rad, g_dist]])
    ki = gains.ki_v_per_rad_s
    # States s = [x⁻ (3), z]; u = −G x̂ + Ki z, z⁺ = z − Ts θ̂ (reference zero).
    cu = np.hstack([-g_fb @ m, [[ki]]])
    du = -g_fb @ ell
    top = np.hstack([a @ m + b @ (-g_fb @ m), b * ki])
    bot = np.hstack([-dt_s * m[0:1, :], [[1.0]]])
    a_c = np.vstack([top, bot])
    b_c = np.vstack([a @ ell + b @ du, -dt_s * ell[0:1, :]])
    if ki == 0.0:  # no integrator: drop its (then unobservable) state
        a_c, b_c, cu = a_c[:3, :3], b_c[:3], cu[:, :3]
    # Output −u (the controller's gain from y with the feedback sign folded in).
    return control.ss(a_c, b_c, -cu, -du, dt_s)


def loop_transfer(
    model: AxisModel, gains: ControllerGains, delay_samples: int = 0, dt_s: float = TS_S
) -> Any:
    """L(z) = C(z)·P(z)·z^-d (negative feedback)."""
    loop = control.series(feedback_controller(model, gains, dt_s), control.tf2ss(plant_zoh(model, dt_s)))
    if delay_samples > 0:
        loop = control.series(control.tf([1.0], [1.0] + [0.0] * delay_samples, dt_s), loop)
    return loop


def check_gains(
    model: AxisModel,
    gains: ControllerGains,
    min_phase_margin_deg: float = 0.0,
    delay_samples: int = 0,
    dt_s: float = TS_S,
) -> DesignReport:
    """Margins and closed-loop stability of ``gains`` on ``model``'s linearised loop."""
    loop = loop_transfer(model, gains, delay_samples, dt_s)
    closed = control.feedback(loop, 1)
    radius = float(np.max(np.abs(closed.poles())))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gms, pms, _, _, wpcs, _ = control.stability_margins(loop, returnall=True)
    stable = radius < 1.0
    # The gain margin that matters for tuning is how much the gain may *rise*; an integrator
    # also makes the loop conditionally stable at low frequency (a gain-reduction margin).
    rising = [float(g) for g in np.atleast_1d(gms) if np.isfinite(g) and g > 1.0]
    gm_db = 20.0 * math.log10(min(rising)) if rising else math.inf
    pms = np.atleast_1d(pms)
    wpcs = np.atleast_1d(wpcs)
    finite = np.isfinite(pms)
    if finite.any():
        i = int(np.argmin(np.where(finite, np.abs(pms), np.inf)))
        pm, wpc = float(pms[i]), float(wpcs[i])
    else:
        pm, wpc = math.nan, math.nan
    pm_deg = float(pm) if np.isfinite(pm) else -180.0
    if not stable:
        pm_deg = min(pm_deg, 0.0)
    wc = float(wpc) if np.isfinite(wpc) else math.nan
    return DesignReport(
        pm_deg, gm_db, wc / (2.0 * math.pi), stable, radius, delay_samples, min_phase_margin_deg
    )


def phase_margin_fast_deg(model: AxisModel, gains: ControllerGains, dt_s: float = TS_S) -> float:
    """Phase margin (deg) of L(z) from its state-space frequency response on a dense grid.

    The design loops' inner function (python-control's ``stability_margins`` falls back to a
    slow FRD search on these loops); :func:`check_gains` reports the python-control figure.
    Returns −180 when |L| never crosses 1.
    """
    loop = control.ss(loop_transfer(model, gains, 0, dt_s))
    a, b, c, d = (np.asarray(m, dtype=float) for m in (loop.A, loop.B, loop.C, loop.D))
    w = np.logspace(-1.0, math.log10(0.999 * math.pi / dt_s), 3000)
    z = np.exp(1j * w * dt_s)
    n = a.shape[0]
    resp = np.linalg.solve(z[:, None, None] * np.eye(n) - a, np.broadcast_to(b, (w.size, *b.shape)))
    l_jw = (c @ resp)[:, 0, 0] + d[0, 0]
    mag = np.abs(l_jw)
    cross = np.flatnonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))
    if cross.size == 0:
        return -180.0
    phase = np.degrees(np.unwrap(np.angle(l_jw)))
    pms = []
    for i in cross:
        f = (mag[i] - 1.0) / (mag[i] - mag[i + 1])
        ph = phase[i] + f * (phase[i + 1] - phase[i])
        pms.append((ph + 360.0) % 360.0 - 180.0)  # 180° + phase, wrapped into [−180°, 180°)
    return float(min(pms))


def seed_lead_gains(model: AxisModel, axis: str) -> LeadGains:
    """The seed's lead, reconstructed (see the module constants).

    Tilt keeps the surviving gain 141 V/rad; pan gets the same loop bandwidth, its gain scaled
    by the inertia ratio (the seed: "the pan controller requires a larger gain due to the
    larger inertia"). The lost zero is then the one that gives the reported phase margin.
    """
    if axis not in SEED_POLES:
        raise ConfigError(f"the seed designed leads for pan and tilt only, not {axis!r}")
    tilt = AxisModel.for_axis("tilt")
    gain = SEED_TILT_GAIN_V_PER_RAD * model.params["inertia.J"] / tilt.params["inertia.J"]
    pole = SEED_POLES[axis]
    target = SEED_PHASE_MARGIN_DEG[axis]

    def pm_error(zero: float) -> float:
        return phase_margin_fast_deg(model, LeadGains(gain, zero, pole)) - target

    zero = brentq(pm_error, pole + 1e-3, 0.99, xtol=1e-7)
    return LeadGains(gain, float(zero), pole)


def observer_pd_gains(
    model: AxisModel,
    crossover_hz: float = 12.0,
    phase_margin_deg: float = 60.0,
    observer_factor: float = 4.0,
    integral_ratio: float = 0.125,
    friction_adapt_per_s: float = 3.0,
) -> ObserverPdGains:
    """Our design: PID on the observer's angle and velocity, plus model feedforward.

    On the double integrator k/s², PD phase lead φ = atan(Kd ωc/Kp) and |C P| = 1 at ωc set
    Kp and Kd; the integral zero sits at ``integral_ratio``·ωc; the observer runs
    ``observer_factor`` times faster than the crossover. The lead angle is then raised until
    the *discrete* loop (ZOH, observer) has ``phase_margin_deg``. The Coulomb feedforward
    adapts to the rig at ``friction_adapt_per_s`` (slow and nonlinear: outside the margins).
    """
    k0 = model.gain_nm_per_v / model.params["inertia.J"]
    wc = 2.0 * math.pi * crossover_hz
    obs_hz = observer_factor * crossover_hz

    def gains_for(lead_deg: float) -> ObserverPdGains:
        t = math.tan(math.radians(lead_deg))
        kp = wc * wc / (k0 * math.sqrt(1.0 + t * t))
        kd = kp * t / wc
        return ObserverPdGains(
            kp, kd, kp * integral_ratio * wc, obs_hz, friction_adapt_per_s=friction_adapt_per_s
        )

    def pm_error(lead_deg: float) -> float:
        return phase_margin_fast_deg(model, gains_for(lead_deg)) - phase_margin_deg

    lo, hi = phase_margin_deg, 85.0
    if pm_error(hi) < 0.0:
        raise ConfigError(
            f"no PD lead reaches {phase_margin_deg:g}° phase margin at a {crossover_hz:g} Hz crossover; "
            "lower the crossover"
        )
    if pm_error(lo) >= 0.0:
        return gains_for(lo)
    return gains_for(float(brentq(pm_error, lo, hi, xtol=1e-3)))


DesignFn = Callable[..., ControllerGains]
CONTROLLERS: dict[str, DesignFn] = {
    "seed_lead": lambda model, axis="pan", **_: seed_lead_gains(model, axis),
    "observer_pd_ff": lambda model, axis="pan", **options: observer_pd_gains(model, **options),
}
DEFAULT_CONTROLLER = "observer_pd_ff"


def design_controller(
    model: AxisModel, name: str = DEFAULT_CONTROLLER, axis: str = "pan", **options: Any
) -> ControllerDesign:
    """Design controller ``name`` (a key of CONTROLLERS) on ``model``; report its margins."""
    if name not in CONTROLLERS:
        raise ConfigError(f"unknown controller {name!r}; known: {', '.join(CONTROLLERS)}")
    key = (
        model.gain_nm_per_v,
        model.effects,
        tuple(sorted(model.params.items())),
        name,
        axis,
        tuple(sorted(options.items())),
    )
    cached = _DESIGNS.get(key)
    if cached is None:
        gains = CONTROLLERS[name](model, axis=axis, **options)
        cached = ControllerDesign(
            name, gains, check_gains(model, gains), check_gains(model, gains, delay_samples=1)
        )
        _DESIGNS[key] = cached
    return cached


# Designs are pure functions of (model, name, options) and take ~1 s: keep them.
_DESIGNS: dict[tuple[Any, ...], ControllerDesign] = {}


@dataclass(frozen=True, slots=True)
class StepPrediction:
    """Predicted step response of ``gains`` on the model's twin; arrays shape (n,).

    ``theta_rad`` is where the load points; figures as in ``tracker simulate``.
    """

    t_s: FloatArray
    target_rad: FloatArray
    theta_rad: FloatArray
    u_v: FloatArray
    rise_time_s: float
    overshoot_percent: float
    settling_time_s: float
    peak_command_v: float


def predicted_step_response(
    model: AxisModel,
    gains: ControllerGains,
    amplitude_rad: float,
    duration_s: float = 1.5,
    shaping: Any = None,
) -> StepPrediction:
    """Simulate a step of ``amplitude_rad`` at t = 0 on ``model`` (+ encoder quantization).

    The full nonlinear loop (Coulomb, the ±10 V clip, the observer, anti-windup) runs, so the
    preview shows what the rig would do. ``shaping`` (TrajectoryLimits) shapes the step as the
    engine does; by default the raw step shows the feedback alone, which is what gains change.
    """
    from tracker.control.closed_loop import simulate_closed_loop

    if not (math.isfinite(amplitude_rad) and amplitude_rad != 0.0):
        raise ConfigError(f"step amplitude {amplitude_rad!r} rad must be a non-zero finite angle")
    if not (math.isfinite(duration_s) and 0.05 <= duration_s <= 60.0):
        raise ConfigError(f"step duration {duration_s!r} s must be within [0.05, 60] s")
    n = int(round(duration_s / TS_S))
    targets = np.full(n, float(amplitude_rad))
    twin = model if model.has("quantization") else model.with_effect("quantization")
    r = simulate_closed_loop(twin, model, gains, targets, TS_S, shaping=shaping)
    y = r.load_theta_rad / amplitude_rad  # normalised: 0 → 1
    above10 = np.flatnonzero(y >= 0.1)
    above90 = np.flatnonzero(y >= 0.9)
    rise = float((above90[0] - above10[0]) * TS_S) if above10.size and above90.size else math.inf
    outside = np.flatnonzero(np.abs(y - 1.0) > 0.02)
    settle = float((outside[-1] + 1) * TS_S) if outside.size else 0.0
    if outside.size and outside[-1] == n - 1:
        settle = math.inf
    return StepPrediction(
        r.t_s,
        r.target_rad,
        r.load_theta_rad,
        r.u_v,
        rise,
        max(0.0, float(y.max()) - 1.0) * 100.0,
        settle,
        float(np.max(np.abs(r.u_v))),
    )
