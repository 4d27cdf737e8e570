"""One simulated log: a true axis, a controller with its program, an encoder → (t, u, θ)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tests.truthgen.axis import TrueAxis
from tests.truthgen.controllers import SIG_OL_A, ControllerDesign, design_replay
from tests.truthgen.encoder import ENCODER_MODES
from tests.truthgen.excitation import empty_program
from tests.truthgen.loop import run_loop

FloatArray = NDArray[np.float64]


@dataclass(slots=True)
class Log:
    """A simulated log and the true angles behind it.

    Attributes
    ----------
    t : ndarray
        Tick times from 0, s.
    u : ndarray
        Logged command, V.
    theta : ndarray
        Logged encoder angle, rad.
    theta_motor, theta_load : ndarray
        True motor/load angles at the ticks, rad.
    """

    t: FloatArray
    u: FloatArray
    theta: FloatArray
    theta_motor: FloatArray
    theta_load: FloatArray


def simulate(
    axis: TrueAxis,
    design: ControllerDesign,
    sig: FloatArray,
    rate_hz: float,
    *,
    latency_samples: int = 0,
    encoder_step: float | None = None,
    encoder_mode: str = "round",
    noise: FloatArray | None = None,
    dist: FloatArray | None = None,
    refine: float = 1.0,
    x0: FloatArray | None = None,
) -> Log:
    """Run the tick loop.

    Parameters
    ----------
    axis : TrueAxis
        The truth.
    design : ControllerDesign
        Controller (kind and coefficients).
    sig : ndarray, shape (N_SIG, n)
        Per-tick program.
    rate_hz : float
        Sample rate, Hz.
    latency_samples : int
        0 or 1: u_i is applied from t_i (0) or t_{i+1} (1), before the plant delay.
    encoder_step : float or None
        Encoder count, rad; ``None``: ``params["quantization.step"]``; 0: no quantization.
    encoder_mode : str
        ``"round"`` or ``"truncate"``.
    noise : ndarray or None
        Measurement noise before quantization (n,), rad.
    dist : ndarray or None
        Load disturbance at the ticks (n+1,), N·m.
    refine : float
        Divides the integration sub-step (convergence checks).
    x0 : ndarray or None
        Initial state (default: :meth:`TrueAxis.initial_state`).
    """
    n = sig.shape[1]
    period = 1.0 / rate_hz
    q = axis.params["quantization.step"] if encoder_step is None else encoder_step
    nz = np.zeros(n) if noise is None else noise
    d = np.zeros(n + 1) if dist is None else dist
    x = axis.initial_state(float(d[0])) if x0 is None else x0
    total_delay = axis.params.get("delay.seconds", 0.0) + latency_samples * period
    u, th, thm, thl = run_loop(
        axis.pack(),
        design.kind,
        design.coeffs,
        np.ascontiguousarray(sig),
        nz,
        d,
        period,
        total_delay,
        q,
        ENCODER_MODES[encoder_mode],
        axis.max_substep(period, refine),
        x,
    )
    return Log(np.arange(n) / rate_hz, u, th, thm, thl)


def replay(axis: TrueAxis, u: FloatArray, rate_hz: float, **kw: object) -> Log:
    """Open-loop response of ``axis`` to the logged command sequence ``u`` (V)."""
    sig = empty_program(len(u))
    sig[SIG_OL_A] = u
    return simulate(axis, design_replay(), sig, rate_hz, **kw)  # type: ignore[arg-type]
