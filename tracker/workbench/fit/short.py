"""Short least-squares fits (the fitter's screens, trials and rival checks) that never compute a
Jacobian nobody reads.

``scipy.optimize.least_squares`` (trust region) differences the Jacobian at every point it
accepts, before it asks whether to go on: a fit that ends there for its evaluation budget or
its callback has just spent one evaluation per coordinate for nothing. On a two-mass model that
is most of a short fit (a stiff belt's screen: 7 evaluations, then 5 more at 7 sub-steps a
sample for a Jacobian it dropped). Here the stop is decided when the point is accepted, before
its Jacobian: the same steps, the same end point and cost, without the dropped evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

FloatArray = NDArray[np.float64]
# Whether a short fit stops at an accepted point: (point, its cost ½Σr², evaluations so far).
StopRule = Callable[[FloatArray, float, int], bool]


@dataclass(frozen=True, slots=True)
class ShortFit:
    """Where a short fit ended: ``x``, its cost ½Σr², and ``status`` as ``least_squares``
    reports it (0: the evaluations ran out; −2: stopped by the rule; > 0: converged)."""

    x: FloatArray
    cost: float
    status: int


class _Stopped(Exception):
    def __init__(self, fit: ShortFit) -> None:
        super().__init__()
        self.fit = fit


def short_least_squares(
    fun: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    diff_step: FloatArray,
    max_nfev: int,
    stop: StopRule | None = None,
) -> ShortFit:
    """``least_squares(fun, x0, bounds=(lower, upper), method="trf", x_scale=1.0,
    diff_step=diff_step, max_nfev=max_nfev)``, stopped at the first accepted point where
    ``stop`` says so (as a ``least_squares`` callback raising ``StopIteration`` would), with no
    Jacobian at the point where it ends.

    Trust-region steps are accepted exactly when their cost falls below the current one
    (``trf``: actual reduction > 0), and an accepted point's Jacobian (``n`` forward differences,
    ``n = x0.size``) is the only thing evaluated right after it, so the evaluations can be told
    apart here: the point, then its differences, then trial steps until one is accepted.
    """
    n = x0.size
    cost = np.inf
    differences_left = 0
    nfev = 0

    def watched(x: FloatArray) -> FloatArray:
        nonlocal cost, differences_left, nfev
        r = fun(x)
        if differences_left > 0:
            differences_left -= 1
            return r
        nfev += 1
        c = 0.5 * float(np.dot(r, r))
        if nfev == 1 or c < cost:
            cost = c
            if nfev > 1:
                if stop is not None and stop(x, c, nfev):
                    raise _Stopped(ShortFit(np.array(x, dtype=float), c, -2))
                if nfev >= max_nfev:
                    raise _Stopped(ShortFit(np.array(x, dtype=float), c, 0))
            differences_left = n
        return r

    try:
        sol = least_squares(
            watched,
            x0,
            bounds=(lower, upper),
            method="trf",
            x_scale=1.0,
            diff_step=diff_step,
            max_nfev=max_nfev,
        )
    except _Stopped as stopped:
        return stopped.fit
    return ShortFit(np.asarray(sol.x, dtype=float), float(sol.cost), int(sol.status))


__all__ = ["ShortFit", "StopRule", "short_least_squares"]
