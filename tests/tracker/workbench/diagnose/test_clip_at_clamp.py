"""A saturation level the command passes only where the controller held it at its own clamp is no
clip (judgement._physical): nothing there shows the torque stop growing with the command.

Outside generator m2 clean-009: a cascade clamped at 8.07 V, 727 of the 732 samples above the
fitted level of 7.91 V held at the clamp (an armature's L/R lag on the largest steps read as a
clip). A true saturation's commands pass its level at many values (independent generators:
at least 1 % of the run outside the clamp).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from tests.truthgen.presets import GAIN_NM_PER_V
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.judgement import MIN_CLIPPED_SHARE, _physical, with_values


def _ctx(u_v: np.ndarray) -> Any:
    """The evidence context the clip rules read: the command, and a residual torque that gathers
    wholly where the command is clipped (so that the clamp rule alone decides here)."""
    return SimpleNamespace(sig=SimpleNamespace(u_v=u_v),
                           concentration=lambda mask: (1.0, float(np.mean(mask))))


def _clip(level_v: float) -> AxisModel:
    base = AxisModel.for_axis("pan", gain_nm_per_v=GAIN_NM_PER_V)
    return with_values(base, {"saturation.limit": level_v}, add="saturation")


def _steps_clamped(rng: np.random.Generator, clamp_v: float, n: int = 20000) -> np.ndarray:
    """A loop's command: mostly under 6 V, its largest steps held at the clamp for 20 samples."""
    u = rng.normal(0.0, 1.5, n).clip(-6.0, 6.0)
    for i in rng.choice(n - 40, 36, replace=False):
        u[i : i + 20] = np.sign(rng.normal()) * clamp_v
        u[i + 20] = 0.99 * clamp_v  # the step's last sample on its way down
    return u


def test_a_level_passed_only_at_the_controller_clamp_is_no_clip() -> None:
    u = _steps_clamped(np.random.default_rng(3), 8.07)
    level = 7.91
    assert float(np.mean(np.abs(u) > level)) >= MIN_CLIPPED_SHARE  # the old count let it through
    assert not _physical("saturation", _clip(level), _ctx(u))


def test_a_level_the_command_passes_at_many_values_is_a_clip() -> None:
    rng = np.random.default_rng(4)
    u = _steps_clamped(rng, 10.0)
    # The true level, 2.3 V: ~1 % of the run above it outside the clamp (6006 dev saturation-002).
    assert _physical("saturation", _clip(2.3), _ctx(u))
    # Without any clamp (a loop that never saturates its own command) as before.
    assert _physical("saturation", _clip(2.3), _ctx(rng.normal(0.0, 1.5, 20000)))
    assert not _physical("saturation", _clip(10.0), _ctx(u))  # the command never passes it
