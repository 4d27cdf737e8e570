"""Head-mounted arrays: the head's pan/tilt over time, and window estimates turned into the base frame.

An array carried on the pan/tilt head measures directions in the head frame (x along the
camera axis), and the head may turn while a window is recorded. The localizers sum the
window's cross-spectra over its STFT frames before normalising (PHAT), so louder parts of the
window weigh more: for the few degrees a head turns within one window, the estimate is the
power-weighted mean of the talker's head-frame direction. The base-frame direction is
therefore recovered with the power-weighted mean of the head's rotation over the window::

    u_base = normalise( sum_k w_k R_world_head(pan(t_k), tilt(t_k)) @ u_head )

with ``t_k`` the centres of ``n`` equal parts of the window and ``w_k`` the audio power in
part ``k`` above the window's quietest part (speech, not the noise floor). This is the exact
form of the seed's "add the encoder angle" (chapter 5) for a moving head: taking the angle at
the window's end instead would lag the talker by half a window times the head's rate (4.5° for
a 0.3 s window while the head turns at 30°/s).

The mean holds while the talker's head-frame direction moves less than the array's beam
width during the window. When the head sweeps further (a 0.3 s window while the camera turns
at 60°/s, or the 1.5 s refining window across any camera move) the window hears the talker
smeared over the sweep and its peak lands anywhere along it, so such a window carries no
direction: its confidence becomes 0 (the tracker skips it) and a refining window's estimate
is dropped. ``MAX_SWEEP_RAD`` (10°) is the sweep of the head's axis, over the loud parts of
the window, beyond which this happens.

The map tracker's azimuth maps (``Pipeline(tracker="map")``) are turned the same way
(:func:`map_to_base`): each head-frame cell moves to the base azimuth its direction has under
the window's mean rotation, and the map is resampled onto the tracker's fixed base-frame grid.
For a level head this is the head-frame map shifted by the window's mean pan; on a tilted head
the maps are still steered at zero head-frame elevation, so a cell is placed where a talker at
the array's height would be (as :func:`direction_to_base` does for a flat array's estimate),
and a talker above or below the head's plane is heard slightly off her true azimuth.

Times are on the audio's clock: seconds from the recording's (or stream's) first sample.
"""

from __future__ import annotations

import csv
import math
import threading
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import rotation_world_head, unit_vector
from tracker.audio.pipeline import FrameEstimate, LocateResult, Pipeline
from tracker.errors import DataError

FloatArray = NDArray[np.float64]
WINDOW_PARTS = 16  # parts of a window whose head rotations are averaged
MAX_SWEEP_RAD = math.radians(10.0)
_LOUD_FRACTION = 0.05  # parts quieter than this fraction of the loudest do not count in a sweep


@dataclass(frozen=True, slots=True)
class HeadMotion:
    """What the head did while one window was recorded.

    Attributes
    ----------
    r_world_head : ndarray, shape (3, 3)
        Power-weighted mean ``R_world_head`` over the window (not exactly a rotation).
    sweep_rad : float
        How far the head's axis swept over the window's loud parts (twice the largest angle
        between a part's axis and their mean axis).
    """

    r_world_head: FloatArray
    sweep_rad: float


class HeadPoses:
    """Time-stamped head angles (encoder readings), appended as they arrive and read by window.

    Thread-safe: one producer (the engine side) adds, the localizer reads. Angles are in rad
    (pan about +z, then tilt up), times in s on the audio clock and increasing; readings older
    than ``keep_s`` before the newest are dropped.
    """

    def __init__(self, keep_s: float = 30.0) -> None:
        self.keep_s = float(keep_s)
        self._lock = threading.Lock()
        self._t: list[float] = []
        self._pan: list[float] = []
        self._tilt: list[float] = []

    @classmethod
    def from_arrays(cls, t_s: FloatArray, pan_rad: FloatArray, tilt_rad: FloatArray,
                    source: str = "head angles") -> HeadPoses:
        """A complete history (an encoder log); arrays of shape (n,), ``t_s`` increasing."""
        t, pan, tilt = (np.asarray(a, dtype=float).ravel() for a in (t_s, pan_rad, tilt_rad))
        if not t.size or not t.size == pan.size == tilt.size:
            raise DataError(f"{source}: need as many times as pan and tilt angles, at least one")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0)) + 1
            raise DataError(f"{source}: time {t[i]:g} s (sample {i + 1}) does not increase")
        poses = cls(keep_s=math.inf)
        poses._t, poses._pan, poses._tilt = t.tolist(), pan.tolist(), tilt.tolist()
        poses._check_finite(source)
        return poses

    def _check_finite(self, source: str) -> None:
        for name, values in (("t", self._t), ("pan", self._pan), ("tilt", self._tilt)):
            if not all(math.isfinite(v) for v in values):
                raise DataError(f"{source}: {name} holds NaN or infinite values")

    def add(self, t_s: float, pan_rad: float, tilt_rad: float) -> None:
        """Append one reading; a repeat of the newest time is ignored, an older time refused."""
        if not (math.isfinite(t_s) and math.isfinite(pan_rad) and math.isfinite(tilt_rad)):
            raise DataError(f"head angles at t={t_s} s: pan {pan_rad}, tilt {tilt_rad} are not finite")
        with self._lock:
            if self._t and t_s <= self._t[-1]:
                if t_s == self._t[-1]:
                    return
                raise DataError(f"head angles at t={t_s:g} s arrive after t={self._t[-1]:g} s")
            self._t.append(float(t_s))
            self._pan.append(float(pan_rad))
            self._tilt.append(float(tilt_rad))
            cut = self._t[-1] - self.keep_s
            if len(self._t) > 64 and self._t[1] < cut:
                k = max(0, int(np.searchsorted(self._t, cut)) - 1)  # keep one before the cut
                del self._t[:k], self._pan[:k], self._tilt[:k]

    def __len__(self) -> int:
        with self._lock:
            return len(self._t)

    @property
    def span_s(self) -> tuple[float, float] | None:
        """First and last reading times (s), or None when empty."""
        with self._lock:
            return (self._t[0], self._t[-1]) if self._t else None

    def angles_at(self, times_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Pan and tilt (rad) at ``times_s``, linear between readings, held beyond the ends.

        Returns two arrays shaped like ``times_s``.
        """
        with self._lock:
            if not self._t:
                raise DataError("no head angles yet: a head-mounted array needs the head's "
                                "encoder angles")
            t, pan, tilt = np.array(self._t), np.array(self._pan), np.array(self._tilt)
        times = np.asarray(times_s, dtype=float)
        return np.interp(times, t, pan), np.interp(times, t, tilt)

    def motion_over(self, start_s: float, end_s: float, weights: FloatArray | None = None
                    ) -> HeadMotion:
        """The head's weighted mean rotation and its sweep over ``[start_s, end_s]``.

        ``weights`` (shape (n_parts,), default uniform over :data:`WINDOW_PARTS`) weigh the
        head's rotation at the centres of ``n_parts`` equal parts of the interval.
        """
        w = np.ones(WINDOW_PARTS) if weights is None else np.asarray(weights, dtype=float)
        centres = start_s + (np.arange(w.size) + 0.5) * (end_s - start_s) / w.size
        pan, tilt = self.angles_at(centres)
        rotations = rotation_world_head(pan, tilt)  # (n_parts, 3, 3)
        total = float(w.sum())
        w = w / total if total > 0 else np.full(w.size, 1.0 / w.size)
        axes = rotations[w >= _LOUD_FRACTION * w.max(), :, 0]  # camera axes of the loud parts
        mean_axis = axes.mean(axis=0)
        mean_axis /= np.linalg.norm(mean_axis)
        deviation = float(np.max(np.arccos(np.clip(axes @ mean_axis, -1.0, 1.0))))
        return HeadMotion(np.asarray(np.einsum("k,kij->ij", w, rotations)), 2.0 * deviation)


def power_weights(window: FloatArray, n_parts: int = WINDOW_PARTS) -> FloatArray:
    """Audio power of ``n_parts`` equal parts of ``window`` (n_mics, n) above its quietest part.

    Returns shape (n_parts,); uniform when the window is equally loud throughout.
    """
    parts = np.array_split(np.asarray(window, dtype=float), n_parts, axis=1)
    power = np.array([float(np.mean(p**2)) if p.size else 0.0 for p in parts])
    power -= power.min()
    return power if power.sum() > 0 else np.ones(n_parts)


def direction_to_base(azimuth_rad: float, elevation_rad: float | None, r_world_head: FloatArray,
                      base_elevation_rad: float = 0.0) -> tuple[float, float | None]:
    """A head-frame direction in the base frame: (azimuth_rad, elevation_rad or None).

    With a known head-frame elevation the unit vector is rotated. A flat array measures only
    the head-frame azimuth ``a`` (the elevation comes back None): the direction is then taken
    on that azimuth's half-circle where the base-frame elevation is ``base_elevation_rad``
    (default 0: the talker at the array's height), solving
    ``cos(e)(r31 cos a + r32 sin a) + r33 sin(e) = sin(base elevation)`` for the head-frame
    elevation ``e`` nearest 0. With the head level (tilt 0) this is plain ``a + pan``.
    """
    r = np.asarray(r_world_head, dtype=float)
    if elevation_rad is not None:
        u = r @ unit_vector(azimuth_rad, elevation_rad)
        norm = float(np.linalg.norm(u))
        return float(math.atan2(u[1], u[0])), float(math.asin(max(-1.0, min(1.0, u[2] / norm))))
    a = float(azimuth_rad)
    horizontal = float(r[2, 0] * math.cos(a) + r[2, 1] * math.sin(a))
    amplitude, phase = math.hypot(horizontal, r[2, 2]), math.atan2(r[2, 2], horizontal)
    spread = math.acos(max(-1.0, min(1.0, math.sin(base_elevation_rad) / max(amplitude, 1e-12))))
    candidates = [math.remainder(phase + s * spread, 2 * math.pi) for s in (1.0, -1.0)]
    e = min(candidates, key=abs)
    e = max(-math.pi / 2, min(math.pi / 2, e))
    u = r @ unit_vector(a, e)
    return float(math.atan2(u[1], u[0])), None


def azimuths_to_base(azimuth_rad: FloatArray, r_world_head: FloatArray) -> FloatArray:
    """Base-frame azimuths of head-frame azimuths measured by a flat array, shape like the input.

    :func:`direction_to_base`'s flat-array case (the talker at the array's height) for many
    azimuths at once: each azimuth's half-circle meets the base frame's horizontal plane at
    the head-frame elevation ``e`` nearest 0 solving ``cos(e)(r31 cos a + r32 sin a) + r33 sin(e) = 0``.
    """
    r = np.asarray(r_world_head, dtype=float)
    a = np.asarray(azimuth_rad, dtype=float)
    horizontal = r[2, 0] * np.cos(a) + r[2, 1] * np.sin(a)
    phase = np.arctan2(r[2, 2], horizontal)
    candidates = np.remainder(np.stack([phase + np.pi / 2, phase - np.pi / 2]) + np.pi,
                              2 * np.pi) - np.pi
    e = np.clip(np.where(np.abs(candidates[0]) <= np.abs(candidates[1]), candidates[0], candidates[1]),
                -np.pi / 2, np.pi / 2)
    u = unit_vector(a, e) @ r.T  # (..., 3) base-frame unit vectors
    return np.asarray(np.arctan2(u[..., 1], u[..., 0]))


def map_to_base(power_map: FloatArray, head_azimuth_rad: FloatArray, base_azimuth_rad: FloatArray,
                r_world_head: FloatArray) -> FloatArray:
    """A head-frame azimuth map resampled onto a base-frame grid (see the module docstring).

    Parameters
    ----------
    power_map : ndarray, shape (n_head,)
        Steered response at ``head_azimuth_rad`` (increasing, evenly spaced, rad).
    base_azimuth_rad : ndarray, shape (n_base,)
        The tracker's base-frame grid (rad).
    r_world_head : ndarray, shape (3, 3)
        The head's (mean) rotation over the window.

    Returns
    -------
    ndarray, shape (n_base,): linear interpolation between the moved head cells (across ±180°
    when the head grid is a full circle). Base cells the head grid does not reach (a head-frame
    search narrower than a full circle) get the map's minimum: nothing is heard there, so no
    talker can be found there.
    """
    p = np.asarray(power_map, dtype=float)
    head = np.asarray(head_azimuth_rad, dtype=float)
    base = np.asarray(base_azimuth_rad, dtype=float)
    moved = np.unwrap(azimuths_to_base(head, r_world_head))  # increasing for a tilt below 90°
    step = (head[-1] - head[0]) / (head.size - 1)
    if head.size * step >= 2 * np.pi - 0.5 * step:  # a full circle: no edge to fall off
        return np.asarray(np.interp(base, moved, p, period=2 * np.pi))
    x = moved[0] + np.remainder(base - moved[0], 2 * np.pi)
    return np.asarray(np.interp(x, moved, p, left=float(p.min()), right=float(p.min())))


def frame_to_base(frame: FrameEstimate, short: HeadMotion, fine: HeadMotion | None,
                  max_sweep_rad: float = MAX_SWEEP_RAD, map_grids: tuple[FloatArray, FloatArray]
                  | None = None) -> FrameEstimate:
    """A head-frame window estimate in the base frame (the short window's and the fine one's).

    A window over which the head swept more than ``max_sweep_rad`` carries no direction: the
    short one gets confidence 0, the fine one is dropped (see the module docstring), and its
    map (if any) becomes NaN, which the map tracker skips. ``map_grids`` (head grid, base
    grid; :attr:`Pipeline.steer_azimuth_rad`, :attr:`Pipeline.map_azimuth_rad`) turns the
    frame's ``power_map`` with :func:`map_to_base`.
    """
    az, el = direction_to_base(frame.azimuth_rad, frame.elevation_rad, short.r_world_head)
    confidence = frame.confidence if short.sweep_rad <= max_sweep_rad else 0.0
    fine_az = frame.fine_azimuth_rad
    if fine_az is not None:
        if fine is None or fine.sweep_rad > max_sweep_rad:
            fine_az = None
        else:
            fine_az = direction_to_base(fine_az, None, fine.r_world_head,
                                        el if el is not None else 0.0)[0]
    power_map = frame.power_map
    if power_map is not None and map_grids is not None:
        head_grid, base_grid = map_grids
        power_map = (map_to_base(power_map, head_grid, base_grid, short.r_world_head)
                     if short.sweep_rad <= max_sweep_rad else np.full(base_grid.shape, np.nan))
    return replace(frame, azimuth_rad=az, elevation_rad=el, confidence=confidence,
                   fine_azimuth_rad=fine_az, power_map=power_map)


def window_motion(poses: HeadPoses, window: FloatArray, start_s: float, end_s: float
                  ) -> HeadMotion:
    """The head's motion while ``window`` (n_mics, n) was recorded, weighted by its power."""
    return poses.motion_over(start_s, end_s, power_weights(window))


def frames_to_base(frames: tuple[FrameEstimate, ...], audio: FloatArray, pipeline: Pipeline,
                   poses: HeadPoses, max_sweep_rad: float = MAX_SWEEP_RAD
                   ) -> tuple[FrameEstimate, ...]:
    """Turn a recording's head-frame window estimates into the base frame (batch)."""
    fs = pipeline.fs_hz
    n_win = int(round(pipeline.windows.window_s * fs))
    fine_s = pipeline.windows.fine_window_s
    n_fine = int(round(fine_s * fs)) if fine_s is not None else 0
    out = []
    for f in frames:
        end = int(round(f.end_s * fs))
        start = end - n_win
        short = window_motion(poses, audio[:, start:end], start / fs, end / fs)
        fine = None
        if f.fine_azimuth_rad is not None:
            lo = max(0, end - n_fine)
            fine = window_motion(poses, audio[:, lo:end], lo / fs, end / fs)
        out.append(frame_to_base(f, short, fine, max_sweep_rad, map_grids(pipeline)))
    return tuple(out)


def map_grids(pipeline: Pipeline) -> tuple[FloatArray, FloatArray] | None:
    """The (head-frame steering, base-frame tracker) azimuth grids of a map-tracking pipeline."""
    if pipeline.tracker != "map":
        return None
    return pipeline.steer_azimuth_rad, pipeline.map_azimuth_rad


def check_coverage(poses: HeadPoses, duration_s: float, tolerance_s: float, source: str) -> None:
    """DataError unless the head angles cover ``[0, duration_s]`` within ``tolerance_s``."""
    span = poses.span_s
    if span is None:
        raise DataError(f"{source}: no head angles")
    if len(poses) > 1 and (span[0] > tolerance_s or span[1] < duration_s - tolerance_s):
        raise DataError(f"{source}: head angles cover {span[0]:.2f}-{span[1]:.2f} s but the "
                        f"recording runs 0-{duration_s:.2f} s")


def locate_head_mounted(pipeline: Pipeline, audio: FloatArray, poses: HeadPoses) -> LocateResult:
    """:meth:`Pipeline.run` for a head-mounted array: frames and track in the base frame.

    ``audio`` has shape (n_mics, n_samples); ``poses`` gives the head's angles on the
    recording's clock.
    """
    frames = pipeline.estimate_frames(audio)
    base = frames_to_base(frames, np.asarray(audio, dtype=float), pipeline, poses)
    return LocateResult(pipeline.fs_hz, pipeline.method, base, pipeline.track(base))


_TIME_COLUMNS = ("t", "t_s")
_ANGLE_COLUMNS = {"pan": 1.0, "pan_rad": 1.0, "pan_deg": math.pi / 180.0,
                  "tilt": 1.0, "tilt_rad": 1.0, "tilt_deg": math.pi / 180.0}


def read_encoder_log(path: str | Path) -> HeadPoses:
    """The head's angles during a recording, from a CSV file.

    Either one file with a header row and columns ``t`` (s, from the recording's first
    sample), ``pan`` and ``tilt`` (rad; or ``pan_deg``/``tilt_deg`` in degrees; other columns
    ignored), one row per encoder reading (a single row: the head did not move); or the
    engine's recording ``RUN.csv`` as ``tracker simulate --record RUN.csv`` writes it:
    ``RUN_pan.csv`` and ``RUN_tilt.csv``, measurement logs (``t``, ``u``, ``theta``).
    Every problem is a :class:`DataError` naming the file (and the line).
    """
    p = Path(path)
    pan_log, tilt_log = (p.with_name(f"{p.stem}_{axis}{p.suffix or '.csv'}") for axis in ("pan", "tilt"))
    if not p.exists() and pan_log.exists() and tilt_log.exists():
        return _from_engine_recording(pan_log, tilt_log)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataError(f"{p}: encoder log not found (nor {pan_log.name} and {tilt_log.name})"
                        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{p}: cannot read the encoder log ({exc})") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise DataError(f"{p}: empty encoder log; expected a header t,pan,tilt")
    header = [h.strip().lower() for h in rows[0]]
    t_col = next((header.index(c) for c in _TIME_COLUMNS if c in header), None)
    cols = {axis: next(((header.index(c), _ANGLE_COLUMNS[c]) for c in _ANGLE_COLUMNS
                        if c.startswith(axis) and c in header), None) for axis in ("pan", "tilt")}
    if t_col is None or cols["pan"] is None or cols["tilt"] is None:
        raise DataError(f"{p}: header {','.join(header)!r} lacks t, pan and tilt "
                        "(angles in rad, or pan_deg/tilt_deg)")
    pan_col, tilt_col = cols["pan"], cols["tilt"]
    values = []
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        try:
            t = float(row[t_col])
            pan, tilt = float(row[pan_col[0]]) * pan_col[1], float(row[tilt_col[0]]) * tilt_col[1]
        except (ValueError, IndexError):
            raise DataError(f"{p}: line {line}: {','.join(row)!r} is not t, pan, tilt numbers"
                            ) from None
        if not all(math.isfinite(v) for v in (t, pan, tilt)):
            raise DataError(f"{p}: line {line}: {','.join(row)!r} is not finite")
        values.append((t, pan, tilt))
    if not values:
        raise DataError(f"{p}: the encoder log has a header but no readings")
    a = np.array(values)
    return HeadPoses.from_arrays(a[:, 0], a[:, 1], a[:, 2], source=str(p))


def _from_engine_recording(pan_log: Path, tilt_log: Path) -> HeadPoses:
    from tracker.workbench.measurements.data import read_log

    pan, tilt = read_log(pan_log), read_log(tilt_log)
    tilt_at = np.interp(pan.t_s, tilt.t_s, tilt.theta_rad)
    return HeadPoses.from_arrays(pan.t_s, pan.theta_rad, tilt_at, source=str(pan_log))
