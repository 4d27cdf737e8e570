"""Compile the engine's numba code into its on-disk cache once, ahead of a user's first request.

The simulator, the k-step judge, the screening and the fit are numba functions compiled on first
use and cached on disk (``cache=True``; ``NUMBA_CACHE_DIR`` or the package's ``__pycache__``).
On a fresh install the first ``tracker model diagnose`` otherwise spends about 90 s compiling
(measured on this project's 2-core machine: 86 s cold, 2.7 s warm, EMPS's 25 s log) before it
says anything. :func:`warm_up` runs the same code paths on a short log of the twin: a
closed-loop run with hidden effects that make every candidate's simulation compile (a delay, a
dead band, a belt), a diagnosis with every candidate, a fit and a comparison with its residual test.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")

#: How long the warm-up log is (s): long enough for the diagnosis' windows and folds.
WARM_LOG_S = 8.0


@dataclass(frozen=True, slots=True)
class WarmUp:
    """What the warm-up ran and how long each stage took (wall clock, s)."""

    stages_s: tuple[tuple[str, float], ...]

    @property
    def total_s(self) -> float:
        return sum(s for _, s in self.stages_s)


def warm_up(progress: Callable[[str], None] | None = None) -> WarmUp:
    """Run the twin, a diagnosis with every candidate and a fit once on a short log, so that
    their compiled code is in the cache; returns the time each stage took."""
    say = progress or (lambda _text: None)
    stages: list[tuple[str, float]] = []

    def stage(name: str, work: Callable[[], T]) -> T:
        say(f"{name} ...")
        t0 = time.perf_counter()
        out = work()
        stages.append((name, time.perf_counter() - t0))
        say(f"{name}: {stages[-1][1]:.1f} s")
        return out

    from tracker.plant.model import AxisModel
    from tracker.workbench.compare.compare import compare_model
    from tracker.workbench.diagnose.diagnose import diagnose
    from tracker.workbench.experiments.experiments import generate_measurement
    from tracker.workbench.fit.fit import fit_model

    base = AxisModel.for_axis("pan")
    meas = stage("the twin's closed loop", lambda: generate_measurement(base, WARM_LOG_S, seed=1))
    stage("diagnose (every candidate)", lambda: diagnose(meas, base))
    with_offset = AxisModel.for_axis("pan", ("offset",))
    stage("fit", lambda: fit_model(meas, with_offset))
    # what `tracker model diagnose` and `compare` also run: the residual test's replayed floor
    stage("compare (residual test)", lambda: compare_model(meas, base, replicas=2))
    return WarmUp(tuple(stages))


__all__ = ["WARM_LOG_S", "WarmUp", "warm_up"]
