"""Microphone array geometry: load and validate the JSON layout, list pairs, rotate head frames.

The JSON file is ``{"mics": [[x, y, z], ...], "mount": ..., "field_of_view": {...}}``.

``mount`` (optional, default ``"room"``) says where the array is. ``"room"``, ``"wall"``,
``"table"`` and ``"ceiling"`` are fixed to the camera base, so the array's frame is the base
frame; ``"head"`` rides on the pan/tilt head (as in the seed), so its estimates are relative to
the head and the head's encoder angles turn them into the base frame (:mod:`tracker.audio.head`).

``field_of_view`` (optional) is where talkers can be: ``{"azimuth_deg": [low, high],
"elevation_deg": [low, high]}``, either key optional, in degrees, in the array's frame (for a
head-mounted array: in the base frame). Its default comes with the mount: a wall has nothing
behind it (azimuth -90..90), a table's talkers sit above it (elevation 0..90), a ceiling's
below it (elevation -90..0); ``"room"`` and ``"head"`` see everywhere. The localizers search
only there and the talker trackers track only there (:class:`FieldOfView`).

Array frame: x forward, y left, z up (metres). A direction is given by its azimuth (from +x toward
+y) and elevation (up from the horizontal plane); its unit vector is
``u = [cos(el) cos(az), cos(el) sin(az), sin(el)]``. A plane wave from ``u`` reaches microphone
``k`` at time ``-u·p_k / c`` relative to the array origin, so the delay of mic ``j`` behind mic
``i`` is ``tau_ij = u·(p_i - p_j) / c``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError
from tracker.units import SPEED_OF_SOUND_M_PER_S

FloatArray = NDArray[np.float64]

# Extents below this are treated as "flat" along that axis (an array cannot resolve it).
_FLAT_TOLERANCE_M = 1e-3
MOUNTS = ("room", "wall", "table", "ceiling", "head")
_KEYS = ("mics", "mount", "field_of_view")
_FOV_KEYS = ("azimuth_deg", "elevation_deg")
_FULL_TURN = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class FieldOfView:
    """Where talkers can be, in the array's frame (rad).

    Attributes
    ----------
    azimuth_rad : (low, high)
        ``low < high``, both within ±2π, at most a full turn apart (a full turn: everywhere).
    elevation_rad : (low, high)
        ``-π/2 <= low < high <= π/2``.
    """

    azimuth_rad: tuple[float, float] = (-math.pi, math.pi)
    elevation_rad: tuple[float, float] = (-math.pi / 2, math.pi / 2)

    def __post_init__(self) -> None:
        (a_lo, a_hi), (e_lo, e_hi) = self.azimuth_rad, self.elevation_rad
        if not (all(math.isfinite(v) for v in (a_lo, a_hi)) and -2 * math.pi <= a_lo < a_hi
                <= 2 * math.pi and a_hi - a_lo <= _FULL_TURN + 1e-9):
            raise ConfigError(f"field of view azimuth {_deg(self.azimuth_rad)}° must be increasing, "
                              "within ±360° and at most 360° wide")
        if not (all(math.isfinite(v) for v in (e_lo, e_hi))
                and -math.pi / 2 - 1e-9 <= e_lo < e_hi <= math.pi / 2 + 1e-9):
            raise ConfigError(f"field of view elevation {_deg(self.elevation_rad)}° must be "
                              "increasing and within ±90°")

    @property
    def full_circle(self) -> bool:
        """True when every azimuth is in view."""
        return self.azimuth_rad[1] - self.azimuth_rad[0] >= _FULL_TURN - 1e-9

    @property
    def azimuth_range_rad(self) -> tuple[float, float] | None:
        """The azimuth range a localizer should search; None for the full circle."""
        return None if self.full_circle else self.azimuth_rad

    def contains_azimuth(self, azimuth_rad: FloatArray | float, margin_rad: float = 0.0
                         ) -> NDArray[np.bool_]:
        """Whether each azimuth is in view (any turn of it), or within ``margin_rad`` of it."""
        lo, hi = self.azimuth_rad
        if self.full_circle:
            return np.ones(np.shape(azimuth_rad), dtype=bool)
        lo, hi = lo - margin_rad, hi + margin_rad
        return np.asarray(np.remainder(np.asarray(azimuth_rad) - lo, _FULL_TURN) <= hi - lo + 1e-9)

    def narrowed(self, azimuth_rad: tuple[float, float], name: str = "array") -> FieldOfView:
        """This view with its azimuths narrowed to ``azimuth_rad`` (low, high; rad, within ±π);
        a ConfigError when they do not overlap."""
        lo, hi = azimuth_rad
        if self.full_circle:
            return FieldOfView((lo, hi), self.elevation_rad)
        own_lo, own_hi = self.azimuth_rad
        shift = _FULL_TURN * round((own_lo + own_hi - lo - hi) / 2.0 / _FULL_TURN)  # same turn
        lo, hi = max(own_lo, lo + shift), min(own_hi, hi + shift)
        if lo >= hi:
            raise ConfigError(f"{name}: azimuths {_deg(azimuth_rad)}° are outside its field of "
                              f"view {_deg(self.azimuth_rad)}°")
        return FieldOfView((lo, hi), self.elevation_rad)

    def nearest_azimuth(self, azimuth_rad: float) -> float:
        """``azimuth_rad`` when in view, else the nearer edge of the view (rad, that edge's turn)."""
        if bool(self.contains_azimuth(azimuth_rad)):
            return azimuth_rad
        lo, hi = self.azimuth_rad
        to_lo = abs(math.remainder(azimuth_rad - lo, _FULL_TURN))
        to_hi = abs(math.remainder(azimuth_rad - hi, _FULL_TURN))
        return lo if to_lo <= to_hi else hi


def _deg(pair: tuple[float, float]) -> list[float]:
    return [round(math.degrees(v), 3) for v in pair]


# What a mount sees unless the file says otherwise.
MOUNT_FIELDS_OF_VIEW = {
    "room": FieldOfView(),
    "wall": FieldOfView(azimuth_rad=(-math.pi / 2, math.pi / 2)),
    "table": FieldOfView(elevation_rad=(0.0, math.pi / 2)),
    "ceiling": FieldOfView(elevation_rad=(-math.pi / 2, 0.0)),
    "head": FieldOfView(),
}


@dataclass(frozen=True, slots=True, eq=False)
class MicArray:
    """A microphone array in its own frame.

    Attributes
    ----------
    positions_m : ndarray, shape (n_mics, 3)
        Microphone positions in metres (x forward, y left, z up).
    name : str
        Where the layout came from (file name or a label), used in error messages.
    mount : {"room", "wall", "table", "ceiling", "head"}
        "room", "wall", "table", "ceiling": fixed to the camera base (estimates are in the base
        frame); "head": carried on the pan/tilt head (estimates are in the head frame, x along
        the camera axis).
    field_of_view : FieldOfView, optional
        Where talkers can be (array frame; base frame for "head"); the mount's default
        (:data:`MOUNT_FIELDS_OF_VIEW`) when not given.
    """

    positions_m: FloatArray
    name: str = "array"
    mount: str = "room"
    field_of_view: FieldOfView = None  # type: ignore[assignment]  # set from the mount
    pairs: tuple[tuple[int, int], ...] = field(init=False)

    def __post_init__(self) -> None:
        if self.mount not in MOUNTS:
            raise ConfigError(f"{self.name}: mount is {self.mount!r}; expected one of "
                              f"{', '.join(map(repr, MOUNTS))}")
        if self.field_of_view is None:
            object.__setattr__(self, "field_of_view", MOUNT_FIELDS_OF_VIEW[self.mount])
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

    @property
    def search_view(self) -> FieldOfView:
        """The view the localizers search, in the array's frame: the field of view, or every
        direction for a head-mounted array (its field of view is the base frame's)."""
        return FieldOfView() if self.head_mounted else self.field_of_view

    @property
    def elevation_range_rad(self) -> tuple[float, float] | None:
        """The elevations a localizer should steer at, or None for the horizontal only.

        An array with height searches its field of view's elevations (within ±80°). A flat
        array hears a source at elevation ``e`` and at ``-e`` alike, and the horizontal is its
        best guess while the view includes it; a view on one side of the array's plane (a
        ceiling's, below it) settles the sign, so it searches there and reports elevation.
        """
        lo, hi = self.search_view.elevation_rad
        limit = math.radians(80.0)
        if self.resolves_elevation:
            return max(lo, -limit), min(hi, limit)
        if lo < 0.0 < hi:  # both sides of the array's plane: no sign to settle
            return None
        return max(lo, -limit), min(hi, limit)

    @property
    def sees_elevation(self) -> bool:
        """True when the localizers estimate elevation (see :attr:`elevation_range_rad`)."""
        return self.elevation_range_rad is not None

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
    """Build a :class:`MicArray` from ``{"mics": [[x, y, z], ...], "mount": ...,
    "field_of_view": {"azimuth_deg": [lo, hi], "elevation_deg": [lo, hi]}}``.

    Positions in metres; ``mount`` (default "room") and ``field_of_view`` (default: the
    mount's) are optional. Unknown keys are refused so that a misspelt ``mount`` cannot
    silently leave a head-mounted array in the room, nor a misspelt view a wall array
    searching behind the wall.
    """
    if not isinstance(data, dict) or "mics" not in data:
        raise ConfigError(f'{name}: expected a JSON object {{"mics": [[x, y, z], ...]}}')
    unknown = sorted(str(k) for k in data if k not in _KEYS)
    if unknown:
        raise ConfigError(f"{name}: unknown key(s) {', '.join(map(repr, unknown))}; "
                          f"an array file has {', '.join(map(repr, _KEYS))}")
    mount = data.get("mount", "room")
    if mount not in MOUNTS:  # also catches non-strings (numbers, null, lists)
        raise ConfigError(f'{name}: "mount" is {json.dumps(mount)}; expected one of '
                          f"{', '.join(map(json.dumps, MOUNTS))}")
    mics = data["mics"]
    if not isinstance(mics, list) or not all(
        isinstance(m, list) and len(m) == 3 and all(isinstance(v, int | float) for v in m)
        for m in mics
    ):
        raise ConfigError(f"{name}: 'mics' must be a list of [x, y, z] number triples in metres")
    view = (field_of_view_from_dict(data["field_of_view"], str(mount), name)
            if "field_of_view" in data else MOUNT_FIELDS_OF_VIEW[str(mount)])
    return MicArray(np.array(mics, dtype=float), name=name, mount=str(mount), field_of_view=view)


def field_of_view_from_dict(data: object, mount: str, name: str = "array") -> FieldOfView:
    """The ``field_of_view`` object of an array file (degrees); keys it lacks keep the
    mount's default. Errors name the file, the key and the value."""
    if not isinstance(data, dict):
        raise ConfigError(f'{name}: "field_of_view" is {json.dumps(data)}; expected an object '
                          '{"azimuth_deg": [low, high], "elevation_deg": [low, high]}')
    unknown = sorted(str(k) for k in data if k not in _FOV_KEYS)
    if unknown:
        raise ConfigError(f"{name}: unknown key(s) {', '.join(map(repr, unknown))} in "
                          f"field_of_view; it has {', '.join(map(repr, _FOV_KEYS))}")
    default = MOUNT_FIELDS_OF_VIEW[mount]
    ranges = {"azimuth_deg": default.azimuth_rad, "elevation_deg": default.elevation_rad}
    for key, (low, high, width) in {"azimuth_deg": (-360.0, 360.0, 360.0),
                                    "elevation_deg": (-90.0, 90.0, 180.0)}.items():
        if key not in data:
            continue
        value = data[key]
        if not (isinstance(value, list) and len(value) == 2
                and all(isinstance(v, int | float) and not isinstance(v, bool)
                        and math.isfinite(v) for v in value)
                and low <= value[0] < value[1] <= high and value[1] - value[0] <= width):
            raise ConfigError(
                f"{name}: field_of_view.{key} is {json.dumps(value)}; expected [low, high] in "
                f"degrees with low < high, both within {low:g}..{high:g}"
                + (", at most 360 apart" if key == "azimuth_deg" else ""))
        ranges[key] = (math.radians(value[0]), math.radians(value[1]))
    return FieldOfView(ranges["azimuth_deg"], ranges["elevation_deg"])


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
