"""Can a log resolve its hidden effect at all? The effect's signature against the log's own noise.

The blind matrix draws effect sizes without regard to the log they land in: a viscous asymmetry
of 5e-4 N·m at 1 rad/s under a 1.6 mN·m disturbance low-passed at 0.8 Hz (some 45 independent
samples in 30 s) is below what any analysis of that log can tell from chance, and "no verdict"
is then the right answer. This module says, per log, whether the hidden effect is resolvable,
so the bench can report the right-first rate on detectable and undetectable cases apart.

It uses the truth (the hidden effect's parameters) and the logged columns only, numpy and scipy
only (nothing of the workbench under test):

* torque effects (offset, Coulomb and viscous asymmetry, gravity, ripple): the effect's torque
  along the logged trajectory, minus the part the base model (inertia, viscous, Coulomb) can
  absorb (least-squares projection), against the residual torque of the *true* structure
  (disturbance, quantization and friction-law mismatch: the log's own noise) and its effective
  number of independent samples (its autocorrelation): ``z = rms(signature) / rms(noise) ·
  √n_eff``, the signature in standard errors. Resolvable when ``z ≥ MIN_Z``.
* backlash: the width against the spread of the encoder's reading (a count either way, or
  ±3σ of the angle noise): a dead band narrower than the reading's flicker at reversals cannot
  be told from it.
* stiction: the torque the axis holds *above Coulomb while at rest*, just before each start
  from rest (the median command over the last moments before the encoder moves, times the
  gain, less the true Coulomb torque of that direction), capped at the true excess ``Fs − Fc``
  (the part static friction can account for) and counted only where positive, in units of the
  log's own torque noise ``σ`` (as for the torque effects: the true structure's residual at
  the narrowest band): ``z = √Σ (held_i/σ)²``. A start after a command step holds nothing
  above Coulomb (the axis breaks away within a sample whatever ``Fs``): only starts where
  the command crept up to the break-away say what it is. The Stribeck velocity against the
  speed resolution (a count per rest window) is reported beside it (``stribeck_resolution``).
* the others (delay, saturation, compliance) act through the dynamics, not as a torque of
  the state: not rated (``None``).
* pairs: a dead band beside gravity is also rated by whether the load ever changes flank
  (:func:`flank_changes`); gravity pressing the load on one flank all through the run leaves
  the gap no trace. Other pairs are not rated (:func:`_pair`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import signal

FloatArray = NDArray[np.float64]

MIN_Z = 5.0  # standard errors: resolvable with a margin under the log's coloured noise
TORQUE_EFFECTS = ("offset", "coulomb_asymmetry", "viscous_asymmetry", "gravity", "ripple")
CUTOFF_HZ = (5.0, 10.0, 25.0)  # the signals' low-passes tried (each at most a tenth of the rate)
MOVING_COUNTS_PER_S = 5.0  # samples slower than this many counts per second are left out (stick)
FLICKER_MIN_COUNTS = 2.0
FLICKER_SIGMAS = 6.0
REST_S = 0.05  # a start from rest: the reading held this long, then moved
# A rest holds a torque when it lasted this many samples beyond the time the axis without static
# friction needs to cover a count (where in the period the count changed; a delay's rounding).
HELD_SLACK_SAMPLES = 2
REST_SIGMAS = 3.0  # with angle noise: at rest while within this many σ of the rest's first reading


def _torque(effect: str, p: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """The hidden effect's resisting torque over the base friction (N·m), in the generator's terms."""
    neg = omega < 0
    if effect == "offset":
        return np.full_like(theta, p["offset.torque"])
    if effect == "coulomb_asymmetry":
        return np.where(neg, -(p["coulomb_asymmetry.negative"] - p["coulomb.torque"]), 0.0)
    if effect == "viscous_asymmetry":
        return np.where(neg, (p["viscous_asymmetry.negative"] - p["viscous.b"]) * omega, 0.0)
    if effect == "gravity":
        return np.asarray(p["gravity.torque"] * np.sin(theta + p["gravity.phase"]), dtype=float)
    if effect == "stiction":
        extra = p["stiction.static_torque"] - p["coulomb.torque"]
        decay = np.exp(-((omega / p["stiction.velocity"]) ** 2))
        return np.asarray(extra * decay * np.sign(omega), dtype=float)
    if effect == "ripple":
        n = p["ripple.cycles_per_rev"]
        return np.asarray(p["ripple.amplitude"] * np.sin(n * theta + p["ripple.phase"]), dtype=float)
    raise ValueError(f"{effect} is not a torque effect")


def effective_samples(x: FloatArray) -> float:
    """Independent samples in a coloured series: n / (1 + 2 Σ ρ_k), summed to the first ρ_k ≤ 0."""
    x = x - x.mean()
    n = x.size
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    if acf[0] <= 0:
        return float(n)
    rho = acf / acf[0]
    below = np.flatnonzero(rho[1:] <= 0.0)
    m = int(below[0]) + 1 if below.size else n
    return float(n / max(1.0, 1.0 + 2.0 * rho[1:m].sum()))


def _signals(
    t: FloatArray, u: FloatArray, theta: FloatArray, cutoff_hz: float
) -> tuple[float, FloatArray, FloatArray, FloatArray, FloatArray]:
    dt = float(np.median(np.diff(t)))
    fc = min(cutoff_hz, 0.1 / dt)
    sos = signal.butter(4, fc, fs=1.0 / dt, output="sos")

    def lp(x: FloatArray) -> FloatArray:
        return np.asarray(signal.sosfiltfilt(sos, x), dtype=float)

    th = lp(theta)
    om = np.gradient(th, dt)
    al = np.gradient(om, dt)
    return dt, lp(u), th, om, al


def _angle_sigma_rad(theta: FloatArray, dt: float) -> float:
    sos = signal.butter(4, min(max(CUTOFF_HZ), 0.1 / dt), fs=1.0 / dt, output="sos")
    r = theta - signal.sosfiltfilt(sos, theta)
    return 1.4826 * float(np.median(np.abs(r - np.median(r))))


def starts_from_rest(theta: FloatArray, step_rad: float, dt: float) -> list[tuple[int, int, float]]:
    """Starts from rest in a log: ``(first rest sample, first moved sample, direction)``.

    At rest while the reading stays within half a count (or ``REST_SIGMAS`` σ of its noise) of
    its first value for at least ``REST_S``.
    """
    tol = max(0.5 * step_rad, REST_SIGMAS * _angle_sigma_rad(theta, dt), 1e-12)
    min_rest = max(2, int(round(REST_S / dt)))
    out: list[tuple[int, int, float]] = []
    start, anchor = 0, float(theta[0])
    moved = np.abs(theta - anchor) > tol
    while True:
        hit = np.flatnonzero(moved[start:])
        if hit.size == 0:
            return out
        k = start + int(hit[0])
        if k - start >= min_rest:
            out.append((start, k, math.copysign(1.0, float(theta[k]) - anchor)))
        start, anchor = k, float(theta[k])
        moved[k:] = np.abs(theta[k:] - anchor) > tol


def reading_spread_rad(theta: FloatArray, step_rad: float, dt: float) -> float:
    """The spread of the encoder's reading about the true angle: 2 counts or ±3σ of its noise."""
    sos = signal.butter(4, min(max(CUTOFF_HZ), 0.1 / dt), fs=1.0 / dt, output="sos")
    r = theta - signal.sosfiltfilt(sos, theta)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return max(FLICKER_MIN_COUNTS * step_rad, FLICKER_SIGMAS * sigma)


def detectability(
    truth: Mapping[str, Any], t: FloatArray, u: FloatArray, theta: FloatArray
) -> dict[str, Any]:
    """How well the log resolves its (single) hidden effect.

    Returns ``{"effect", "measure", "value", "detectable"}``: ``measure`` "z" (torque effects,
    standard errors) or "width/spread" (backlash); ``detectable`` None when not rated (clean
    logs, pairs, effects that act through the dynamics).
    """
    hidden = list(truth["hidden"])
    if len(hidden) == 2:
        return _pair(truth, t, u, theta)
    if len(hidden) != 1:
        return {"effect": "+".join(hidden) or None, "measure": None, "value": None, "detectable": None}
    effect = hidden[0]
    p = {k: float(v) for k, v in truth["params"].items()}
    step = p.get("quantization.step", 0.0)
    if effect == "backlash":
        dt = float(np.median(np.diff(t)))
        ratio = p["backlash.width"] / reading_spread_rad(theta, step, dt)
        return {"effect": effect, "measure": "width/spread", "value": ratio, "detectable": ratio >= 1.0}
    if effect == "stiction":
        return _stiction(p, truth, t, u, theta)
    if effect not in TORQUE_EFFECTS:
        return {"effect": effect, "measure": None, "value": None, "detectable": None}
    # An analysis may choose its bandwidth: the best of a few (a ripple needs a wide one, a
    # slow signature under quantization noise a narrow one).
    z = max(_z(effect, p, truth, t, u, theta, fc) for fc in CUTOFF_HZ)
    return {"effect": effect, "measure": "z", "value": z, "detectable": z >= MIN_Z}


def _pair(truth: Mapping[str, Any], t: FloatArray, u: FloatArray, theta: FloatArray) -> dict[str, Any]:
    """A pair of effects: rated where the other effect can take away all of one's trace.

    A dead band beside gravity: the load leaves the flank gravity presses it on only where the
    torque the drive must pass to it, ``J_load·α + Tg·sin(θ + φ)``, changes sign (beyond the load
    disturbance's RMS either way: :func:`flank_changes`). A gap that is never crossed leaves no
    trace in the log, however wide it is; one that is crossed is rated as a single dead band
    (its width against the reading's spread). Every other pair is not rated (a torque effect
    beside another shares part of its signature, but what the rests and starts tell apart, a
    bias from a Coulomb asymmetry under gravity, is beyond a regression on the moving samples).

    Returns ``{"effect", "measure", "value", "detectable", "effects"}``: ``detectable`` False
    when an effect of the pair is rated undetectable, else None.
    """
    hidden = list(truth["hidden"])
    p = {k: float(v) for k, v in truth["params"].items()}
    rated: dict[str, dict[str, Any]] = {}
    if set(hidden) == {"backlash", "gravity"}:
        single = detectability({**truth, "hidden": ["backlash"]}, t, u, theta)
        flips = flank_changes(p, truth, t, theta)
        rated["backlash"] = {
            "measure": single["measure"],
            "value": single["value"],
            "flank_changes": flips,
            "detectable": bool(single["detectable"]) and flips > 0,
        }
    if set(hidden) == {"stiction", "delay"}:
        rated["stiction"] = _stiction_behind_delay(p, truth, t, u, theta)
    verdicts = [r["detectable"] for r in rated.values()]
    return {
        "effect": "+".join(hidden),
        "measure": "pair",
        "value": None,
        "detectable": False if False in verdicts else None,
        "effects": rated,
    }


def _stiction_behind_delay(
    p: Mapping[str, float], truth: Mapping[str, Any], t: FloatArray, u: FloatArray, theta: FloatArray
) -> dict[str, Any]:
    """Static friction beside a transport delay: rated as a single stiction on the command as it
    reaches the axis (the logged command delayed by the true delay and the log's computational
    latency, in whole samples).

    The torque the axis holds at rest is the delayed command's: on the logged command, a step
    past the break-away shows as "held" for the delay's length before every start (an 18 ms delay
    against the rating's 4 ms skip), so an open-loop step program whose steps all start the axis
    at once would be rated detectable by the delay alone.
    """
    dt = float(np.median(np.diff(t)))
    lag = p.get("delay.seconds", 0.0) + int(truth.get("latency_samples", 0)) * dt
    n = int(round(lag / dt))
    at_axis = np.concatenate([np.full(n, u[0]), u[: u.size - n]]) if 0 < n < u.size else u
    single = _stiction(p, truth, t, at_axis, theta)
    return {
        "measure": single["measure"],
        "value": single["value"],
        "rests": single["rests"],
        "holding": single["holding"],
        "delay_samples": n,
        "detectable": bool(single["detectable"]),
    }


def flank_changes(p: Mapping[str, float], truth: Mapping[str, Any], t: FloatArray, theta: FloatArray) -> int:
    """How often the torque passed to the load, ``J_load·α + Tg·sin(θ + φ)``, changes sign by more
    than the load disturbance's RMS either way: each is the load crossing its dead band.

    The logged angle is the motor's (the load lags it by at most half the gap, which moves the
    sine by a fraction of a degree); α from it low-passed at the widest band of the ratings."""
    dt = float(np.median(np.diff(t)))
    _, _, th, _, al = _signals(t, np.zeros_like(theta), theta, max(CUTOFF_HZ))
    j_load = p["inertia.J"] * (1.0 - p["inertia.motor_fraction"])
    passed = j_load * al + p.get("gravity.torque", 0.0) * np.sin(th + p.get("gravity.phase", 0.0))
    edge = max(1, int(round(0.05 / dt)))
    passed = passed[edge:-edge]
    band = float(truth.get("noise", {}).get("disturbance_rms_nm", 0.0))
    side = np.where(passed > band, 1, np.where(passed < -band, -1, 0))
    held = side[side != 0]
    return int(np.count_nonzero(held[1:] != held[:-1]))


def _travel_s(net_nm: float, j: float, b: float, count_rad: float) -> float:
    """Time a rigid axis from rest needs to cover ``count_rad`` under a net torque ``net_nm``
    (inertia ``j``, viscous ``b``): θ(t) = (F/b)·(t − (1 − e^(−b·t/J))·J/b); inf if not positive.
    (``tracker.workbench.diagnose.rests`` solves the same equation; this rating imports nothing
    from ``tracker`` on purpose, so that it cannot share a mistake with the judge it rates.)"""
    if net_nm <= 0:
        return math.inf
    rigid = math.sqrt(2.0 * count_rad * j / net_nm)
    if b <= 0:
        return rigid
    tau = j / b

    def covered(x: float) -> float:
        return (net_nm / b) * (x - tau * -math.expm1(-x / tau))

    lo, hi = 0.0, rigid
    while covered(hi) < count_rad:
        hi *= 2.0
        if hi > 1e6:
            return math.inf
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if covered(mid) < count_rad else (lo, mid)
    return hi


def _longest_run(mask: NDArray[np.bool_]) -> int:
    if not mask.any():
        return 0
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return int(np.max(np.flatnonzero(d == -1) - np.flatnonzero(d == 1)))


def _stiction(
    p: Mapping[str, float], truth: Mapping[str, Any], t: FloatArray, u: FloatArray, theta: FloatArray
) -> dict[str, Any]:
    """The torque the axis holds above Coulomb at rest, against the disturbance and Coulomb's
    uncertainty.

    A rest's held torque is the highest excess over Coulomb, up to the true excess ``Fs − Fc``
    (a torque beyond the break-away is not held), that the command kept, never beyond the
    break-away, for long enough that the axis without static friction would have covered a whole
    encoder count in it (from rest, at that excess; plus ``HELD_SLACK_SAMPLES`` for where in the
    period the count changed and a delay's rounding to samples). After a step past
    the break-away the axis starts at once, and the time it then needs to reach the next count
    (19 ms on a 1000-count encoder at 0.05 N·m net) holds nothing: only a torque that stayed
    above Coulomb longer than that, the axis still, says that static friction held it.
    """
    dt = float(np.median(np.diff(t)))
    step = p.get("quantization.step", 0.0)
    k = float(truth["gain_nm_per_v"])
    excess = max(p["stiction.static_torque"] - p["coulomb.torque"], 0.0)
    fc_neg = p.get("coulomb_asymmetry.negative", p["coulomb.torque"])
    j, b = p["inertia.J"], p.get("viscous.b", 0.0)
    torque = k * u
    over = np.abs(torque) - np.where(torque >= 0, p["coulomb.torque"], fc_neg)
    rests = starts_from_rest(theta, step, dt)
    held = []
    for first, first_moved, _ in rests:
        seg = over[first : first_moved - 1]  # the sample the reading moved at belongs to the start
        best = 0.0
        holdable = (seg > 0.0) & (seg <= excess)  # above Coulomb, below the break-away
        for level in np.unique(seg[holdable]):
            need = _travel_s(float(level), j, b, max(step, 1e-12)) + HELD_SLACK_SAMPLES * dt
            if level > best and _longest_run(holdable & (seg >= level)) * dt >= need:
                best = float(level)
        held.append(best)
    h = np.array(held, dtype=float)
    sigma_d = float(truth.get("noise", {}).get("disturbance_rms_nm", 0.0))
    se_fc = _coulomb_se(p, truth, t, u, theta, min(CUTOFF_HZ))
    sigma = math.hypot(sigma_d, se_fc)
    if sigma > 0:
        z = float(np.sqrt(np.sum((h / sigma) ** 2)))
    else:
        z = math.inf if h.any() else 0.0
    speed_res = max(step, 1e-12) / REST_S
    return {
        "effect": "stiction",
        "measure": "held/noise",
        "value": z,
        "detectable": z >= MIN_Z,
        "rests": len(held),
        "holding": int(np.count_nonzero(h > 0.5 * excess)),
        "excess_over_noise": excess / sigma if sigma > 0 else math.inf,
        "stribeck_resolution": p["stiction.velocity"] / speed_res,
    }


def _moving_signals(
    p: Mapping[str, float], t: FloatArray, u: FloatArray, theta: FloatArray, cutoff_hz: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """:func:`_signals` and the samples where the axis moves (clear of the run's first and
    last 50 ms), as the regressions on moving data use them."""
    step = p.get("quantization.step", 0.0)
    dt, u_lp, th, om, al = _signals(t, u, theta, cutoff_hz)
    moving = np.abs(om) > MOVING_COUNTS_PER_S * max(step, 1e-9)
    edge = max(1, int(round(0.05 / dt)))
    moving[:edge] = moving[-edge:] = False
    return u_lp, th, om, al, moving


def _coulomb_se(
    p: Mapping[str, float],
    truth: Mapping[str, Any],
    t: FloatArray,
    u: FloatArray,
    theta: FloatArray,
    cutoff_hz: float,
) -> float:
    """Standard error of the Coulomb torque a regression on the moving samples gets (true
    structure, Stribeck known), under the log's coloured residual (effective samples)."""
    u_lp, th, om, al, moving = _moving_signals(p, t, u, theta, cutoff_hz)
    if moving.sum() < 10:
        return math.inf
    y = float(truth["gain_nm_per_v"]) * u_lp[moving] - _torque("stiction", p, th[moving], om[moving])
    x = np.column_stack([al[moving], om[moving], np.sign(om[moving])])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ coef
    sigma2 = float(res @ res) / max(1, y.size - 3)
    cov = np.linalg.pinv(x.T @ x) * sigma2 * y.size / max(effective_samples(res), 1.0)
    return float(np.sqrt(max(cov[2, 2], 0.0)))


def _z(
    effect: str,
    p: Mapping[str, float],
    truth: Mapping[str, Any],
    t: FloatArray,
    u: FloatArray,
    theta: FloatArray,
    cutoff_hz: float,
) -> float:
    """The effect's torque signature in standard errors of the log's own noise at one bandwidth."""
    u_lp, th, om, al, moving = _moving_signals(p, t, u, theta, cutoff_hz)
    if moving.sum() < 10:
        return 0.0
    k = float(truth["gain_nm_per_v"])
    y = k * u_lp[moving]
    base = np.column_stack([al[moving], om[moving], np.sign(om[moving])])
    tau = _torque(effect, p, th[moving], om[moving])
    # The log's own noise: what the true structure leaves (with the effect's torque known).
    full = np.column_stack([base, tau])
    coef, *_ = np.linalg.lstsq(full, y, rcond=None)
    noise = y - full @ coef
    # The signature: the effect's torque less what the base model absorbs.
    c2, *_ = np.linalg.lstsq(base, tau, rcond=None)
    sig = tau - base @ c2
    sigma = float(np.sqrt(np.mean(noise**2)))
    if sigma <= 0:
        return math.inf
    return float(np.sqrt(np.mean(sig**2)) / sigma * math.sqrt(effective_samples(noise)))


__all__ = [
    "MIN_Z",
    "detectability",
    "effective_samples",
    "flank_changes",
    "reading_spread_rad",
    "starts_from_rest",
]
