"""The simulated rig (the default driver): both axes as AxisModel twins with encoder quantization
and hidden effects from a config file, so measurements with effects the model lacks come on demand.

Config (JSON)::

    {"pan":  {"effects": ["gravity"], "params": {"gravity.torque": 0.02}},
     "tilt": {"effects": [], "params": {}}}

Each axis starts from the seed preset (:mod:`tracker.plant.params`) plus ``quantization``
(the seed's encoder); missing axes get the preset. Time advances one sample per :meth:`tick`
(all axes together); :meth:`run_closed_loop` is the compiled fast path used by the engine.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.control.closed_loop import N_REC, history_length, run_chunk
from tracker.drivers.motor import AXES, FaultLatch
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.plant.params import get_preset
from tracker.plant.simulate import advance, encoder_rad, initial_state, pack_params

FloatArray = NDArray[np.float64]
DT_S = 1e-3
# Mechanical end stops: this far past the soft limit the rig latches an over-travel fault (and
# the axis rests against the stop).
HARD_STOP_MARGIN_RAD = math.radians(5.0)


def rig_models(config: Mapping[str, Any] | None = None) -> dict[str, AxisModel]:
    """The twin of each axis from a config mapping (see the module docstring)."""
    cfg = dict(config or {})
    unknown = sorted(set(cfg) - set(AXES))
    if unknown:
        raise ConfigError(f"rig config: unknown axis {', '.join(unknown)}; axes are {', '.join(AXES)}")
    models: dict[str, AxisModel] = {}
    for axis in AXES:
        spec = cfg.get(axis) or {}
        if not isinstance(spec, Mapping):
            raise ConfigError(f"rig config: {axis} must be an object with 'effects' and 'params'")
        effects = spec.get("effects", [])
        params = spec.get("params", {})
        if isinstance(effects, str) or not isinstance(params, Mapping):
            raise ConfigError(f"rig config: {axis}.effects must be a list and {axis}.params an object")
        try:
            models[axis] = AxisModel.for_axis(axis, ["quantization", *effects], dict(params))
        except ConfigError as exc:
            raise ConfigError(f"rig config: {axis}: {exc}") from None
    return models


def load_rig_config(path: str | Path) -> dict[str, AxisModel]:
    """Read a rig config file (JSON) into the twin of each axis."""
    p = Path(path)
    try:
        cfg = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"rig config {p}: no such file") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"rig config {p}: line {exc.lineno}: {exc.msg}") from None
    if not isinstance(cfg, dict):
        raise ConfigError(f"rig config {p}: expected a JSON object with 'pan'/'tilt'")
    try:
        return rig_models(cfg)
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None


class SimDriver(FaultLatch):
    """The simulated pan/tilt rig. ``models`` maps axis → twin (default: the seed presets)."""

    def __init__(self, models: Mapping[str, AxisModel] | None = None, dt_s: float = DT_S) -> None:
        self._models = dict(rig_models()) if models is None else dict(models)
        missing = [a for a in AXES if a not in self._models]
        if missing:
            raise ConfigError(f"SimDriver: no model for axis {', '.join(missing)}")
        self._dt = float(dt_s)
        self._p = {a: pack_params(m, self._dt) for a, m in self._models.items()}
        self._x = {a: initial_state() for a in AXES}
        self._hist = {a: np.zeros(history_length(self._p[a], self._dt)) for a in AXES}
        self._u = {a: 0.0 for a in AXES}
        self._hard = {a: get_preset(a).soft_limit_rad + HARD_STOP_MARGIN_RAD for a in AXES}
        self._enabled = False
        self._faults: list[str] = []
        self.samples = 0

    @classmethod
    def from_config(cls, path: str | Path) -> SimDriver:
        """A rig with the hidden effects of a config file."""
        return cls(load_rig_config(path))

    @classmethod
    def from_models(cls, models: Mapping[str, AxisModel]) -> SimDriver:
        """A rig with the given twins."""
        return cls(models)

    # -- MotorDriver ---------------------------------------------------------------------
    @property
    def axes(self) -> tuple[str, ...]:
        return AXES

    @property
    def sample_period_s(self) -> float:
        return self._dt

    @property
    def sample_time_s(self) -> float:
        return self.samples * self._dt

    @property
    def enabled(self) -> bool:
        return self._enabled

    @property
    def models(self) -> dict[str, AxisModel]:
        """The twins (with their hidden effects)."""
        return dict(self._models)

    def enable(self) -> None:
        self.refuse_if_faulted()
        self._enabled = True

    def disable(self) -> None:
        self._enabled = False
        for a in AXES:
            self._u[a] = 0.0

    def command(self, axis: str, volts: float) -> None:
        self._check_axis(axis)
        if not math.isfinite(volts):
            self.latch_fault(f"{axis}: command {volts!r} V is not finite")
            return
        self._u[axis] = float(volts) if self._enabled else 0.0

    def read_encoder(self, axis: str) -> float:
        self._check_axis(axis)
        return float(encoder_rad(self._x[axis], self._p[axis]))

    def tick(self) -> None:
        for a in AXES:
            h = self._hist[a]
            h[:-1] = h[1:]
            h[-1] = self._u[a] if self._enabled else 0.0
            advance(self._x[a], self._p[a], h, h.size - 1, self._dt, 0.0)
            self._check_travel(a)
        self.samples += 1

    # -- the twin's extras ---------------------------------------------------------------
    def load_angle_rad(self, axis: str) -> float:
        """Where the load (camera) really points: ground truth the encoder may not show."""
        self._check_axis(axis)
        return float(self._x[axis][2])

    def set_angle(self, axis: str, theta_rad: float) -> None:
        """Place ``axis`` at rest at ``theta_rad`` (test setup)."""
        self._check_axis(axis)
        self._x[axis][:] = initial_state(theta_rad)

    def run_closed_loop(
        self, axis: str, cp: FloatArray, cs: FloatArray, targets_rad: FloatArray
    ) -> FloatArray:
        """The compiled fast path: see :class:`tracker.drivers.motor.ClosedLoopDriver`."""
        self._check_axis(axis)
        tgt = np.ascontiguousarray(targets_rad, dtype=float)
        rec = np.zeros((tgt.size, N_REC))
        n = run_chunk(
            self._p[axis],
            cp,
            cs,
            self._x[axis],
            self._hist[axis],
            tgt,
            np.zeros(0),
            self._enabled,
            self._hard[axis],
            rec,
        )
        self._u[axis] = float(rec[n - 1, 1]) if n else 0.0
        if n < tgt.size:
            rec[n:] = rec[n - 1]
            self._check_travel(axis)
        return rec

    def _check_travel(self, axis: str) -> None:
        x = self._x[axis]
        th = x[2]
        hard = self._hard[axis]
        if abs(th) > hard:
            self.latch_fault(
                f"{axis}: over-travel at {math.degrees(th):.1f}° (end stop ±{math.degrees(hard):.1f}°)"
            )
            # The end stop is a wall: the axis rests against it (motor and load together), so
            # that once the fault is cleared the guard can drive it back inside.
            x[0] += math.copysign(hard, th) - th
            x[2] = math.copysign(hard, th)
            x[1] = 0.0
            x[3] = 0.0

    def _check_axis(self, axis: str) -> None:
        if axis not in self._models:
            raise ConfigError(f"unknown axis {axis!r}; the rig has {', '.join(AXES)}")
