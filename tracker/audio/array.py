"""Microphone array geometry: load and validate the JSON layout, list pairs, rotate head frames.

The JSON file is ``{"mics": [[x, y, z], ...], "mount": "room" | "head"}``. ``mount`` is
optional (default ``"room"``): a room-mounted array is fixed to the camera base, so its frame
is the base frame; a head-mounted one rides on the pan/tilt head (as in the seed), so its
estimates are relative to the head and the head's encoder angles turn them into the base
frame (:mod:`tracker.audio.head`).

Array frame: x forward, y left, z up (metres). A direction is given by its azimuth (from +x toward
+y) and elevation (up from the horizontal plane); its unit vector is
``u = [cos(el) cos(az), cos(el) sin(az), sin(el)]``. A plane wave from ``u`` reaches microphone
``k`` at time ``-u·p_k / c`` relative to the array origin, so the delay of mic ``j`` behind mic
``i`` is ``tau_ij = u·(p_i - p_j) / c``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError
from tracker.units import SPEED_OF_SOUND_M_PER_S

FloatArray = NDArray[np.float64]

# Extents below this are treated as "flat" along that axis (an array cannot resolve it).
_FLAT_TOLERANCE_M = 1e-3
MOUNTS = ("room", "head")
_KEYS = ("mics", "mount")


@dataclass(frozen=True, slots=True, eq=False)
class MicArray:
    """A microphone array in its own frame.

    Attributes
    ----------
    positions_m : ndarray, shape (n_mics, 3)
        Microphone positions in metres (x forward, y left, z up).
    name : str
        Where the layout came from (file name or a label), used in error messages.
    mount : {"room", "head"}
        "room": fixed to the camera base (estimates are in the base frame); "head": carried
        on the pan/tilt head (estimates are in the head frame, x along the camera axis).
    """

    positions_m: FloatArray
    name: str = "array"
    mount: str = "room"
    pairs: tuple[tuple[int, int], ...] = field(init=False)

    def __post_init__(self) -> None:
        if self.mount not in MOUNTS:
            raise ConfigError(f'{self.name}: mount is {self.mount!r}; expected "room" or "head"')
        positions = np.asarray(self.positions_m, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 3:
            raise ConfigError(
                f"{self.name}: mics must be a list of [x, y, z] in metres, got shape {positions.shape}"
            )
        if positions.shape[0] < 2:
            raise ConfigError(f"{self.name}: need at least 2 microphones, got {positions.shape[0]}")
        if not np.all(np.isfinite(positions)):
            raise ConfigError(f"{self.name}: mic positions must be finite numbers")
        if np.any(np.abs(positions) > 5.0):
            raise ConfigError(f"{self.name}: a mic lies more than 5 m from the origin; use metres")
        n = positions.shape[0]
        separations = np.linalg.norm(positions[:, None, :] - positions[None, :, :], axis=-1)
        separations[np.arange(n), np.arange(n)] = np.inf
        if np.min(separations) < 1e-3:
            i, j = np.unravel_index(np.argmin(separations), separations.shape)
            raise ConfigError(f"{self.name}: mics {i} and {j} are closer than 1 mm")
        positions.setflags(write=False)
        object.__setattr__(self, "positions_m", positions)
        object.__setattr__(
            self, "pairs", tuple((i, j) for i in range(n) for j in range(i + 1, n))
        )

    @property
    def head_mounted(self) -> bool:
        """True when the array rides on the pan/tilt head (its estimates need the encoder angles)."""
        return self.mount == "head"

    @property
    def n_mics(self) -> int:
        """Number of microphones."""
        return int(self.positions_m.shape[0])

    @property
    def baselines_m(self) -> FloatArray:
        """Pair baselines ``p_i - p_j``; shape (n_pairs, 3)."""
        i, j = np.array(self.pairs).T
        return np.asarray(self.positions_m[i] - self.positions_m[j], dtype=float)

    @property
    def max_lag_s(self) -> FloatArray:
        """Physical lag limit ``|p_i - p_j| / c`` of each pair; shape (n_pairs,)."""
        return np.asarray(np.linalg.norm(self.baselines_m, axis=1) / SPEED_OF_SOUND_M_PER_S)

    @property
    def extent_m(self) -> FloatArray:
        """Span of the array along x, y and z; shape (3,)."""
        return np.asarray(np.ptp(self.positions_m, axis=0), dtype=float)

    @property
    def resolves_elevation(self) -> bool:
        """True when the mics span the z axis, so elevation is observable."""
        return bool(self.extent_m[2] > _FLAT_TOLERANCE_M)

    @property
    def resolves_front_back(self) -> bool:
        """True when the mics span the x axis, so front and back azimuths differ."""
        return bool(self.extent_m[0] > _FLAT_TOLERANCE_M)

    def delays_s(self, directions: FloatArray) -> FloatArray:
        """Plane-wave pair delays ``tau_ij = u·(p_i - p_j) / c``.

        Parameters
        ----------
        directions : ndarray, shape (..., 3)
            Unit vectors toward the source.

        Returns
        -------
        ndarray, shape (..., n_pairs)
        """
        # Written out rather than a matrix product: the same direction gives the same delays
        # to the last bit however many directions are asked for at once (BLAS may round a
        # batch differently), so a window's estimate does not depend on its neighbours.
        u = np.asarray(directions, dtype=float)[..., None, :]
        b = self.baselines_m
        return np.asarray((u[..., 0] * b[:, 0] + u[..., 1] * b[:, 1] + u[..., 2] * b[:, 2])
                          / SPEED_OF_SOUND_M_PER_S)


def unit_vector(azimuth_rad: FloatArray | float, elevation_rad: FloatArray | float) -> FloatArray:
    """Unit direction vectors; shape ``broadcast(az, el).shape + (3,)``."""
    az = np.asarray(azimuth_rad, dtype=float)
    el = np.asarray(elevation_rad, dtype=float)
    cos_el = np.cos(el)
    return np.stack(np.broadcast_arrays(cos_el * np.cos(az), cos_el * np.sin(az), np.sin(el)), -1)


def array_from_dict(data: object, name: str = "array") -> MicArray:
    """Build a :class:`MicArray` from ``{"mics": [[x, y, z], ...], "mount": "room" | "head"}``.

    Positions in metres; ``mount`` is optional (default "room"). Unknown keys are refused so
    that a misspelt ``mount`` cannot silently leave a head-mounted array in the room.
    """
    if not isinstance(data, dict) or "mics" not in data:
        raise ConfigError(f'{name}: expected a JSON object {{"mics": [[x, y, z], ...]}}')
    unknown = sorted(str(k) for k in data if k not in _KEYS)
    if unknown:
        raise ConfigError(f"{name}: unknown key(s) {', '.join(map(repr, unknown))}; "
                          f"an array file has {', '.join(map(repr, _KEYS))}")
    mount = data.get("mount", "room")
    if mount not in MOUNTS:  # also catches non-strings (numbers, null, lists)
        raise ConfigError(f'{name}: "mount" is {json.dumps(mount)}; expected "room" or "head"')
    mics = data["mics"]
    if not isinstance(mics, list) or not all(
        isinstance(m, list) and len(m) == 3 and all(isinstance(v, int | float) for v in m)
        for m in mics
    ):
        raise ConfigError(f"{name}: 'mics' must be a list of [x, y, z] number triples in metres")
    return MicArray(np.array(mics, dtype=float), name=name, mount=str(mount))


def load_array(path: str | Path) -> MicArray:
    """Read and validate an array geometry JSON file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: array file not found") from exc
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path}: not a readable JSON array file ({exc})") from exc
    return array_from_dict(data, name=str(path))


def rotation_world_head(pan_rad: FloatArray | float, tilt_rad: FloatArray | float) -> FloatArray:
    """``R_world_head`` for a head panned by ``pan_rad`` (about +z) then tilted up by ``tilt_rad``.

    Maps vectors in the head frame (x along the camera axis) into the base/world frame;
    shape ``broadcast(pan, tilt).shape + (3, 3)`` (so (3, 3) for scalars). Tilting up lifts
    +x toward +z, a rotation of ``-tilt`` about +y.
    """
    pan, tilt = np.broadcast_arrays(np.asarray(pan_rad, dtype=float),
                                    np.asarray(tilt_rad, dtype=float))
    cp, sp, ct, st = np.cos(pan), np.sin(pan), np.cos(tilt), np.sin(tilt)
    zero = np.zeros_like(cp)
    # R_pan @ R_tilt written out: columns are the head's x, y, z axes in the base frame.
    rows = [[cp * ct, -sp, -cp * st], [sp * ct, cp, -sp * st], [st, zero, ct]]
    return np.asarray(np.stack([np.stack(r, axis=-1) for r in rows], axis=-2))


@dataclass(frozen=True, slots=True)
class Direction:
    """A direction as azimuth and elevation in radians."""

    azimuth_rad: float
    elevation_rad: float


def head_to_world(
    azimuth_rad: float, elevation_rad: float, pan_rad: float, tilt_rad: float
) -> Direction:
    """Turn a direction measured by a head-mounted array into the base frame.

    The seed added the encoder angle to the measured angle (chapter 5); this is the exact
    version of that, which matters once tilt is not small.
    """
    u_world = rotation_world_head(pan_rad, tilt_rad) @ unit_vector(azimuth_rad, elevation_rad)
    return Direction(
        azimuth_rad=float(np.arctan2(u_world[1], u_world[0])),
        elevation_rad=float(np.arcsin(np.clip(u_world[2], -1.0, 1.0))),
    )
