"""Simulated rooms (pyroomacoustics shoebox): talkers that take turns or walk, with known directions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from tracker.audio.array import MicArray
from tracker.errors import ConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class RoomSettings:
    """A shoebox room and its acoustics.

    Attributes
    ----------
    size_m : (x, y, z) room dimensions in metres.
    rt60_s : reverberation time (Sabine), 0.1-1.5 s.
    snr_db : speech-to-noise ratio at the mics over active speech; noise is independent white
        noise per mic (self-noise and diffuse room noise).
    fs_hz : sample rate.
    max_order : cap on image-source order (speed); None uses Sabine's estimate.
    """

    size_m: tuple[float, float, float] = (6.0, 5.0, 3.0)
    rt60_s: float = 0.4
    snr_db: float = 10.0
    fs_hz: int = 16000
    max_order: int | None = None

    def __post_init__(self) -> None:
        if not 0.05 <= self.rt60_s <= 1.5:
            raise ConfigError(f"rt60_s={self.rt60_s} outside 0.05-1.5 s")
        if min(self.size_m) <= 0.5:
            raise ConfigError(f"room size_m={self.size_m} too small")


@dataclass(frozen=True, slots=True, eq=False)
class Placement:
    """Where the array sits in the room: centre position (m) and yaw of its +x axis (rad)."""

    position_m: FloatArray
    yaw_rad: float = 0.0

    def rotation(self) -> FloatArray:
        """``R_room_array``; shape (3, 3)."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def to_room(self, points_array_m: FloatArray) -> FloatArray:
        """Array-frame points to room coordinates; shape (n, 3) in and out."""
        return np.asarray(points_array_m) @ self.rotation().T + self.position_m

    def directions(self, points_room_m: FloatArray) -> FloatArray:
        """Azimuth and elevation (rad) of room points seen from the array; shape (n, 2)."""
        v = (np.atleast_2d(points_room_m) - self.position_m) @ self.rotation()
        az = np.arctan2(v[:, 1], v[:, 0])
        el = np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]))
        return np.stack([az, el], axis=1)


def wall_placement(settings: RoomSettings, distance_m: float = 0.15, height_m: float = 1.2
                   ) -> Placement:
    """Array ``distance_m`` from the x=0 wall, halfway along it, facing into the room (+x)."""
    return Placement(np.array([distance_m, settings.size_m[1] / 2, height_m]), 0.0)


def centre_placement(settings: RoomSettings, height_m: float = 1.2) -> Placement:
    """Array in the middle of the floor plan."""
    return Placement(np.array([settings.size_m[0] / 2, settings.size_m[1] / 2, height_m]), 0.0)


@dataclass(frozen=True, slots=True, eq=False)
class Talker:
    """A talker: a mono signal and a path.

    Attributes
    ----------
    samples : ndarray, shape (n_samples,)
        What the talker says over the whole simulation (zeros while silent).
    active : ndarray of bool, shape (n_samples,)
        Ground-truth voice activity.
    path_times_s : ndarray, shape (n_points,)
        Increasing waypoint times; one point for a talker who stands still.
    path_m : ndarray, shape (n_points, 3)
        Mouth positions in room coordinates at those times (linear in between).
    """

    samples: FloatArray
    active: NDArray[np.bool_]
    path_times_s: FloatArray
    path_m: FloatArray

    def position_at(self, times_s: FloatArray) -> FloatArray:
        """Mouth position at ``times_s``; shape (n_times, 3)."""
        times = np.atleast_1d(np.asarray(times_s, dtype=float))
        return np.stack(
            [np.interp(times, self.path_times_s, self.path_m[:, k]) for k in range(3)], axis=1
        )

    @property
    def moves(self) -> bool:
        """True when the path has more than one distinct point."""
        return bool(np.ptp(self.path_m, axis=0).max() > 1e-6) if len(self.path_m) > 1 else False


@dataclass(frozen=True, slots=True, eq=False)
class Recording:
    """A simulated multichannel recording with its ground truth.

    Attributes
    ----------
    audio : ndarray, shape (n_mics, n_samples)
    fs_hz : int
    talkers : tuple of Talker
    placement : Placement
    """

    audio: FloatArray
    fs_hz: int
    talkers: tuple[Talker, ...]
    placement: Placement
    settings: RoomSettings = field(default_factory=RoomSettings)

    @property
    def duration_s(self) -> float:
        """Length in seconds."""
        return self.audio.shape[1] / self.fs_hz

    def directions(self, times_s: FloatArray) -> FloatArray:
        """True azimuth/elevation (rad) of every talker; shape (n_talkers, n_times, 2)."""
        return np.stack([self.placement.directions(t.position_at(times_s)) for t in self.talkers])

    def activity(self, times_s: FloatArray, window_s: float = 0.0) -> FloatArray:
        """Fraction of ``[t - window_s/2, t + window_s/2]`` each talker is active; (n_talkers, n_times)."""
        times = np.atleast_1d(np.asarray(times_s, dtype=float))
        half = max(1, int(window_s * self.fs_hz / 2))
        out = np.zeros((len(self.talkers), times.size))
        for k, talker in enumerate(self.talkers):
            cumulative = np.concatenate([[0], np.cumsum(talker.active)])
            centre = np.round(times * self.fs_hz).astype(int)
            lo = np.clip(centre - half, 0, talker.active.size)
            hi = np.clip(centre + half, 0, talker.active.size)
            out[k] = (cumulative[hi] - cumulative[lo]) / np.maximum(hi - lo, 1)
        return out


def simulate(
    settings: RoomSettings,
    array: MicArray,
    placement: Placement,
    talkers: list[Talker] | tuple[Talker, ...],
    seed: int = 0,
    segment_s: float = 0.1,
) -> Recording:
    """Render talkers through the shoebox to the array and add noise.

    A walking talker is rendered as a sequence of ``segment_s`` pieces, each convolved with
    the room response at its position and cross-faded (50 % overlapping Hann windows), so the
    image-source model can represent movement. All room responses come from one
    ``compute_rir`` call.

    Returns
    -------
    Recording, audio shape (n_mics, n_samples) with n_samples the longest talker signal.
    """
    import pyroomacoustics as pra  # heavy import; only simulations need it

    fs = settings.fs_hz
    mics_room = placement.to_room(array.positions_m)
    size = np.array(settings.size_m)
    if np.any(mics_room < 0.01) or np.any(mics_room > size - 0.01):
        raise ConfigError("array lies outside the room")
    absorption, max_order = pra.inverse_sabine(settings.rt60_s, list(settings.size_m))
    if settings.max_order is not None:
        max_order = min(max_order, settings.max_order)
    room = pra.ShoeBox(list(settings.size_m), fs=fs, materials=pra.Material(absorption),
                       max_order=max_order)
    room.add_microphone_array(mics_room.T)
    n_samples = max(t.samples.size for t in talkers)
    hop = int(round(segment_s * fs))
    plan: list[tuple[int, int]] = []  # (talker, segment start sample); -1 start = whole signal
    for k, talker in enumerate(talkers):
        if talker.moves:
            starts = np.arange(-hop, talker.samples.size, hop)
            centres = (starts + hop) / fs
            for start, position in zip(starts, talker.position_at(centres), strict=True):
                room.add_source(np.clip(position, 0.05, size - 0.05))
                plan.append((k, int(start)))
        else:
            room.add_source(np.clip(talker.path_m[0], 0.05, size - 0.05))
            plan.append((k, -1))
    room.compute_rir()
    rir_len = max(len(room.rir[m][s]) for m in range(array.n_mics) for s in range(len(plan)))
    audio = np.zeros((array.n_mics, n_samples + rir_len))
    fade = np.hanning(2 * hop + 1)[:-1]  # overlapping halves sum to one
    for source, (k, start) in enumerate(plan):
        samples = talkers[k].samples
        if start < 0:
            piece, offset = samples, 0
        else:
            lo, hi = max(start, 0), min(start + 2 * hop, samples.size)
            if hi <= lo:
                continue
            piece, offset = samples[lo:hi] * fade[lo - start : hi - start], lo
        if not np.any(piece):
            continue
        for m in range(array.n_mics):
            out = signal.oaconvolve(piece, room.rir[m][source])
            audio[m, offset : offset + out.size] += out
    audio = audio[:, :n_samples]
    audio = _add_noise(audio, talkers, settings.snr_db, np.random.default_rng(seed))
    return Recording(audio, fs, tuple(talkers), placement, settings)


def _add_noise(audio: FloatArray, talkers: list[Talker] | tuple[Talker, ...], snr_db: float,
               rng: np.random.Generator) -> FloatArray:
    """Add white noise at ``snr_db`` below the mean speech power while anyone talks."""
    any_active = np.zeros(audio.shape[1], dtype=bool)
    for talker in talkers:
        any_active[: talker.active.size] |= talker.active[: audio.shape[1]]
    speech_power = np.mean(audio[:, any_active] ** 2) if any_active.any() else np.mean(audio**2)
    noise_std = np.sqrt(speech_power / 10 ** (snr_db / 10))
    return np.asarray(audio + noise_std * rng.standard_normal(audio.shape))


def static_talker(samples: FloatArray, active: NDArray[np.bool_], position_m: FloatArray
                  ) -> Talker:
    """A talker who stands at ``position_m`` (room coordinates)."""
    return Talker(samples, active, np.zeros(1), np.atleast_2d(np.asarray(position_m, float)))


def position_from_direction(placement: Placement, azimuth_rad: float, distance_m: float,
                            mouth_height_m: float = 1.2) -> FloatArray:
    """Room point ``distance_m`` away horizontally at ``azimuth_rad`` (array frame), at mouth height."""
    v_array = np.array([np.cos(azimuth_rad), np.sin(azimuth_rad), 0.0]) * distance_m
    point = placement.to_room(v_array[None, :])[0]
    point[2] = mouth_height_m
    return point
