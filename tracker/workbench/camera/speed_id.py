"""Speed-table identification: the camera's friction-ID. Each speed step, in each direction,
held from rest until the rate is steady; the steady rate measured from the reported angle;
the measured table set against the profile file's.

Runs on any :class:`SpeedRig`: :class:`TwinRig` (the emulator's twin on a simulated clock,
instant) or :class:`ViscaRig` (a :class:`tracker.drivers.visca.ViscaCamera`, in real time —
against a real camera or ``tracker camera-emulator``).

Per step k (console frame): drive +k for ``hold`` seconds, stop, let it settle; then −k, so the
head ends near where it started. ``hold`` is long enough to reach the profile's speed at the
profile's acceleration (three times over) and then cover ``MIN_COUNTS`` counts, shortened to stay
inside the limits. The rate is the slope of a straight line through the positions of the last
half of the hold (time-stamped at the middle of each inquiry's round trip), its standard error
from the line's residuals.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from tracker.drivers import visca_protocol as vp
from tracker.drivers.camera_profiles import CameraProfile
from tracker.drivers.camera_twin import CameraTwin
from tracker.errors import ConfigError, DataError, JobCancelled

MIN_COUNTS = 120
MIN_HOLD_S = 0.4
MAX_HOLD_S = 4.0
SETTLE_PERIODS = 4


class SpeedRig(Protocol):
    """What the identification needs from a camera (console frame, rad, s)."""

    period_s: float
    limits_rad: dict[str, tuple[float, float]]

    @property
    def profile(self) -> CameraProfile:
        """The profile file's figures the result is set against."""
        ...

    async def drive(self, axis: str, step: int, direction: int) -> None:
        """Drive ``axis`` at speed ``step`` toward ``direction`` (+1/-1); 0 stops it."""
        ...

    async def position(self, axis: str) -> tuple[float, float]:
        """(time s, angle rad) as reported now."""
        ...

    async def wait(self, seconds: float) -> None:
        """Let time pass."""
        ...


@dataclass
class TwinRig:
    """The emulator's twin on a simulated clock (5 ms steps): instant. ``file_profile`` is the file's
    profile the result is set against (default: the twin's own)."""

    twin: CameraTwin
    file_profile: CameraProfile | None = None
    period_s: float = 0.04
    latency_s: float = 0.0
    limits_rad: dict[str, tuple[float, float]] = field(default_factory=dict)
    now_s: float = 0.0
    _pending: list[tuple[float, tuple[int, int, int, int]]] = field(default_factory=list)

    @property
    def profile(self) -> CameraProfile:
        return self.file_profile or self.twin.profile

    def __post_init__(self) -> None:
        if not self.limits_rad:
            self.limits_rad = dict(self.twin.profile.range_rad)

    async def drive(self, axis: str, step: int, direction: int) -> None:
        pan_dir = tilt_dir = 3
        code = max(1, step)
        visca = direction * self.twin.profile.sign[axis]
        if axis == "pan" and visca:
            pan_dir = 2 if visca > 0 else 1
        if axis == "tilt" and visca:
            tilt_dir = 1 if visca > 0 else 2
        self._pending.append((self.now_s + self.latency_s, (code, code, pan_dir, tilt_dir)))

    async def position(self, axis: str) -> tuple[float, float]:
        pan, tilt = self.twin.position_counts()
        return self.now_s, self.twin.profile.to_rad(axis, pan if axis == "pan" else tilt)

    async def wait(self, seconds: float) -> None:
        end = self.now_s + seconds
        while self.now_s < end - 1e-12:
            dt = min(0.005, end - self.now_s)
            due = [p for p in self._pending if p[0] <= self.now_s]
            for p in due:
                self.twin.drive(*p[1])
                self._pending.remove(p)
            self.twin.step(dt)
            self.now_s += dt


class ViscaRig:
    """A connected, enabled :class:`tracker.drivers.visca.ViscaCamera` (its supervisor sends no
    steering while it has no target, so the identification's drives are the only ones)."""

    def __init__(self, camera: Any) -> None:  # noqa: ANN401 - a ViscaCamera (no import cycle)
        self.camera = camera
        self._profile: CameraProfile = camera.profile
        self.period_s: float = camera.command_period_s
        self.limits_rad = {a: camera.limits(a) for a in ("pan", "tilt")}

    @property
    def profile(self) -> CameraProfile:
        return self._profile

    async def drive(self, axis: str, step: int, direction: int) -> None:
        if not self.camera.enabled:
            raise DataError(f"camera {self.camera.spec.url} was disabled during the identification")
        visca = direction * self.profile.sign[axis]
        pan_dir, tilt_dir = vp.PAN_STOP, vp.TILT_STOP
        if axis == "pan" and visca:
            pan_dir = vp.PAN_RIGHT if visca > 0 else vp.PAN_LEFT
        if axis == "tilt" and visca:
            tilt_dir = vp.TILT_UP if visca > 0 else vp.TILT_DOWN
        await self.camera.command(vp.pan_tilt_drive(max(1, step), max(1, step), pan_dir, tilt_dir))

    async def position(self, axis: str) -> tuple[float, float]:
        sent = time.monotonic()
        pan, tilt = await self.camera.inquire_position()
        return 0.5 * (sent + time.monotonic()), pan if axis == "pan" else tilt

    async def wait(self, seconds: float) -> None:
        await asyncio.sleep(seconds)


@dataclass(frozen=True, slots=True)
class StepRate:
    """One run: the steady rate of ``step`` toward ``direction``."""

    step: int
    direction: int
    rate_rad_s: float
    stderr_rad_s: float
    profile_rad_s: float
    samples: int

    @property
    def deviation_percent(self) -> float:
        return 100.0 * (self.rate_rad_s / self.profile_rad_s - 1.0)


@dataclass(frozen=True, slots=True)
class SpeedIdResult:
    """The measured speed table against the profile's."""

    axis: str
    profile: str
    runs: tuple[StepRate, ...]
    elapsed_s: float
    notes: tuple[str, ...]

    def table(self, direction: int) -> dict[int, float]:
        """Measured rate (rad/s) per step in ``direction``."""
        return {r.step: r.rate_rad_s for r in self.runs if r.direction == direction}

    @property
    def max_deviation_percent(self) -> float:
        return max((abs(r.deviation_percent) for r in self.runs), default=0.0)

    def params(self) -> dict[str, float]:
        """The measured steps in the camera model's names (``speed_table.positive.K`` ...)."""
        out = {}
        for r in self.runs:
            out[f"speed_table.{'positive' if r.direction > 0 else 'negative'}.{r.step}"] = r.rate_rad_s
        return out

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": "speed-id",
            "axis": self.axis,
            "profile": self.profile,
            "elapsed_s": self.elapsed_s,
            "max_deviation_percent": self.max_deviation_percent,
            "runs": [
                {
                    "step": r.step,
                    "direction": r.direction,
                    "rate_rad_s": r.rate_rad_s,
                    "stderr_rad_s": r.stderr_rad_s,
                    "profile_rad_s": r.profile_rad_s,
                    "deviation_percent": r.deviation_percent,
                    "samples": r.samples,
                }
                for r in self.runs
            ],
            "params": self.params(),
            "notes": list(self.notes),
        }


def default_steps(profile: CameraProfile, axis: str, count: int) -> tuple[int, ...]:
    """``count`` steps spread over the table (always the slowest and the fastest)."""
    n = len(profile.speeds_rad_s[axis])
    if count >= n:
        return tuple(range(1, n + 1))
    return tuple(sorted({int(round(x)) for x in np.linspace(1, n, max(2, count))}))


def _line(t: list[float], y: list[float]) -> tuple[float, float]:
    tt, yy = np.asarray(t), np.asarray(y)
    a = np.column_stack((tt - tt.mean(), np.ones_like(tt)))
    coef, *_ = np.linalg.lstsq(a, yy, rcond=None)
    res = yy - a @ coef
    s2 = float(np.sum(res**2)) / max(1, tt.size - 2)
    sxx = float(np.sum((tt - tt.mean()) ** 2))
    return float(coef[0]), math.sqrt(s2 / sxx) if sxx > 0 else math.inf


async def _run_one(rig: SpeedRig, axis: str, step: int, direction: int, hold_s: float) -> StepRate:
    """Drive, sample every command period, stop, settle; the rate over the hold's second half."""
    await rig.drive(axis, step, direction)
    t0, _ = await rig.position(axis)
    ts: list[float] = []
    ys: list[float] = []
    while True:
        await rig.wait(rig.period_s)
        t, y = await rig.position(axis)
        if t - t0 >= hold_s:
            break
        if t - t0 >= 0.5 * hold_s:
            ts.append(t)
            ys.append(y)
    await rig.drive(axis, step, 0)
    expected = rig.profile.code_speed_rad_s(axis, step)
    await rig.wait(expected / rig.profile.accel_rad_s2 + SETTLE_PERIODS * rig.period_s)
    if len(ts) < 3:
        raise DataError(
            f"step {step}: only {len(ts)} positions in the hold's second half; "
            f"the command period {rig.period_s:g} s is too long for a {hold_s:.2f} s hold"
        )
    rate, se = _line(ts, ys)
    return StepRate(step, direction, direction * rate, se, expected, len(ts))


async def identify_speed_table(
    rig: SpeedRig,
    axis: str = "pan",
    *,
    steps: tuple[int, ...] | None = None,
    count: int = 8,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> SpeedIdResult:
    """Measure the speed table of ``axis`` (see the module docstring)."""
    if axis not in ("pan", "tilt"):
        raise ConfigError(f"unknown axis {axis!r}; the camera has pan, tilt")
    prof = rig.profile
    n = len(prof.speeds_rad_s[axis])
    chosen = default_steps(prof, axis, count) if steps is None else tuple(steps)
    bad = [s for s in chosen if not 1 <= s <= n]
    if bad:
        raise ConfigError(f"steps {bad} are outside the {prof.name} profile's {axis} table 1..{n}")
    lo, hi = rig.limits_rad[axis]
    runs: list[StepRate] = []
    notes: list[str] = []
    start = time.monotonic()
    total = 2 * len(chosen)
    for i, step in enumerate(chosen):
        v = prof.code_speed_rad_s(axis, step)
        ramp = v / prof.accel_rad_s2
        for j, direction in enumerate((1, -1)):
            hold = min(MAX_HOLD_S, max(MIN_HOLD_S, 3 * ramp + 0.2, 2 * MIN_COUNTS * prof.rad_per_count / v))
            if cancel is not None and cancel():
                await rig.drive(axis, 1, 0)
                raise JobCancelled("speed-table identification cancelled")
            _, here = await rig.position(axis)
            room = (hi - here if direction > 0 else here - lo) - 2 * prof.rad_per_count
            travel = v * hold + v * ramp
            if travel > room:
                hold = max(0.0, (room - v * ramp) / v)
                if hold < max(MIN_HOLD_S, 2.2 * ramp):  # the second half must be steady
                    notes.append(
                        f"step {step} {'+' if direction > 0 else '-'}: skipped, only "
                        f"{math.degrees(room):.1f}° of room to the limit"
                    )
                    continue
            runs.append(await _run_one(rig, axis, step, direction, hold))
            if progress is not None:
                progress((2 * i + j + 1) / total)
    if not runs:
        raise DataError(f"no step could be measured on {axis}: no room between the limits")
    worst = max(runs, key=lambda r: abs(r.deviation_percent))
    notes.append(
        f"largest departure from the {prof.name} profile: step {worst.step} "
        f"{'+' if worst.direction > 0 else '-'} {worst.deviation_percent:+.1f} %"
    )
    return SpeedIdResult(axis, prof.name, tuple(runs), time.monotonic() - start, tuple(notes))
