"""Simulated rooms heard by an array on the pan/tilt head: the head turns and the mics turn with it."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import MicArray, rotation_world_head
from tracker.audio.room import Placement, Recording, RoomSettings, Talker, simulate
from tracker.errors import ConfigError

FloatArray = NDArray[np.float64]


def simulate_head_mounted(
    settings: RoomSettings,
    array: MicArray,
    position_m: FloatArray,
    talkers: list[Talker] | tuple[Talker, ...],
    head_t_s: FloatArray,
    head_pan_rad: FloatArray,
    head_tilt_rad: FloatArray,
    grid_rad: float = math.radians(2.5),
    seed: int = 0,
) -> Recording:
    """Render talkers to a head-mounted array whose head follows a pan/tilt path.

    The head's centre sits at ``position_m`` (room coordinates) with its base frame aligned
    with the room (pan 0 looks along +x), so the returned recording's ``placement`` and
    ``directions`` give the talkers' true base-frame directions. The head's angles are linear
    between the waypoints ``(head_t_s, head_pan_rad, head_tilt_rad)`` (shape (n,) each; held
    beyond the ends). The room is rendered once per head orientation on a ``grid_rad`` grid
    of pan and tilt (array rotated by ``R_world_head``, same noise and room for every
    orientation) and the renderings are blended sample by sample with bilinear weights of the
    head's angle between grid nodes: a head that stands on a grid node is exact, a turning
    head is approximated to a fraction of ``grid_rad``.

    Returns
    -------
    Recording, audio shape (n_mics, n_samples).
    """
    if not 0 < grid_rad <= math.radians(10.0):
        raise ConfigError(f"grid_rad={grid_rad} must be in (0, 10°]")
    fs = settings.fs_hz
    n_samples = max(t.samples.size for t in talkers)
    times = np.arange(n_samples) / fs
    pan = np.interp(times, head_t_s, head_pan_rad) / grid_rad
    tilt = np.interp(times, head_t_s, head_tilt_rad) / grid_rad
    p0, t0 = np.floor(pan), np.floor(tilt)
    fp, ft = pan - p0, tilt - t0
    placement = Placement(np.asarray(position_m, dtype=float), 0.0)
    weights: dict[tuple[int, int], FloatArray] = {}
    for dp, dt in ((0, 0), (1, 0), (0, 1), (1, 1)):
        weight = (fp if dp else 1 - fp) * (ft if dt else 1 - ft)
        nodes = np.stack([p0 + dp, t0 + dt], axis=1)[weight > 0].astype(int)
        for node in {(int(a), int(b)) for a, b in np.unique(nodes, axis=0)}:
            on_node = (p0 + dp == node[0]) & (t0 + dt == node[1])
            weights.setdefault(node, np.zeros(n_samples))[on_node] += weight[on_node]
    audio = np.zeros((array.n_mics, n_samples))
    for (i, j), weight in sorted(weights.items()):
        rotated = _rotated(array, i * grid_rad, j * grid_rad)
        audio += weight * simulate(settings, rotated, placement, talkers, seed=seed).audio
    return Recording(audio, fs, tuple(talkers), placement, settings)


def _rotated(array: MicArray, pan_rad: float, tilt_rad: float) -> MicArray:
    """The array's mics in the base frame for a head at (pan, tilt), as a room-mounted array."""
    positions = array.positions_m @ rotation_world_head(pan_rad, tilt_rad).T
    return MicArray(positions, name=f"{array.name} at pan {math.degrees(pan_rad):.1f}°, "
                    f"tilt {math.degrees(tilt_rad):.1f}°")
