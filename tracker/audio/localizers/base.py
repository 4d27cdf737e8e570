"""The localizer interface: one window of multichannel audio in, one direction estimate out."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import MicArray, unit_vector
from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class DirectionEstimate:
    """One direction estimate in the array frame.

    Attributes
    ----------
    azimuth_rad : float
        From +x toward +y, in (-pi, pi].
    elevation_rad : float or None
        Up from horizontal; None when the array cannot observe it (all mics in one z plane).
    confidence : float
        In [0, 1]; the method's own peak strength (normalised SRP/GCC peak, or 0 when it found
        nothing).
    """

    azimuth_rad: float
    elevation_rad: float | None
    confidence: float


class Localizer(Protocol):
    """A direction-of-arrival method bound to one array and sample rate."""

    name: str
    array: MicArray
    fs_hz: int

    def locate(self, frame: FloatArray) -> DirectionEstimate:
        """Estimate the dominant source direction in ``frame``, shape (n_mics, n_samples)."""
        ...


def check_frame(frame: FloatArray, array: MicArray, min_samples: int) -> FloatArray:
    """Validate a window of audio; returns it as float64, shape (n_mics, n_samples)."""
    frame = np.asarray(frame, dtype=float)
    if frame.ndim != 2 or frame.shape[0] != array.n_mics:
        raise DataError(
            f"audio window has shape {frame.shape}, expected ({array.n_mics}, n_samples) "
            f"for {array.name}"
        )
    if frame.shape[1] < min_samples:
        raise DataError(f"audio window has {frame.shape[1]} samples, need at least {min_samples}")
    if not np.all(np.isfinite(frame)):
        raise DataError("audio window contains NaN or infinite samples")
    return frame


def direction_grid(
    array: MicArray,
    azimuth_step_rad: float,
    elevation_step_rad: float,
    azimuth_range_rad: tuple[float, float] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Candidate directions the array can tell apart, within its field of view.

    Azimuth spans the field of view (:attr:`MicArray.search_view`; the full circle when the
    array has depth along x and sees everywhere), and at most the front half (-90°..90°) when
    the array has no depth along x; ``azimuth_range_rad`` replaces the field of view's range
    (an array on a wall, or under a camera that cannot turn around, has nothing to find behind
    it). Elevation spans :attr:`MicArray.elevation_range_rad` (the view's elevations within
    ±80° for an array with height), else 0 only.

    Returns
    -------
    azimuth_rad, elevation_rad : ndarray, shape (n_grid,) each
    """
    if azimuth_range_rad is None:
        azimuth_range_rad = array.search_view.azimuth_range_rad
    if azimuth_range_rad is not None:
        lo, hi = azimuth_range_rad
        if not (-2 * np.pi <= lo < hi <= 2 * np.pi):
            raise ConfigError(f"azimuth_range_rad={azimuth_range_rad} must be increasing, within ±2π")
        if not array.resolves_front_back:
            lo, hi = max(lo, -np.pi / 2), min(hi, np.pi / 2)
            if lo >= hi:
                raise ConfigError(f"{array.name}: azimuths {np.rad2deg(azimuth_range_rad)}° are "
                                  "outside the -90°..90° an array without depth along x can tell")
        az = np.linspace(lo, hi, max(2, int(round((hi - lo) / azimuth_step_rad)) + 1))
    elif array.resolves_front_back:
        az = np.arange(-np.pi, np.pi, azimuth_step_rad)
    else:
        az = np.linspace(-np.pi / 2, np.pi / 2, int(round(np.pi / azimuth_step_rad)) + 1)
    elevation_range = array.elevation_range_rad
    if elevation_range is not None:
        lo, hi = elevation_range
        el = np.linspace(lo, hi, max(1, int(round((hi - lo) / elevation_step_rad))) + 1)
    else:
        el = np.zeros(1)
    az_grid, el_grid = np.meshgrid(az, el, indexing="ij")
    return az_grid.ravel(), el_grid.ravel()


def grid_vectors(azimuth_rad: FloatArray, elevation_rad: FloatArray) -> FloatArray:
    """Unit vectors for a grid; shape (n_grid, 3)."""
    return unit_vector(azimuth_rad, elevation_rad)


def wrap_angle(angle_rad: FloatArray | float) -> FloatArray:
    """Wrap into (-pi, pi]."""
    return np.asarray(-((-np.asarray(angle_rad) + np.pi) % (2 * np.pi) - np.pi))
