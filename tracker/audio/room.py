"""Simulated rooms (pyroomacoustics shoebox): talkers that take turns or walk, with known directions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

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
    ism_order : image-source order. The image sources are exact but their number grows with
        the cube of the order (Sabine's order for RT60 0.4 s here is 53: 0.3 s per source);
        order 10 renders the first ~80 ms exactly, after which a diffuse late tail
        (:func:`late_tail`) with the right decay and inter-mic coherence takes over.
        None renders the whole response with image sources (slow, for checks).
    """

    size_m: tuple[float, float, float] = (6.0, 5.0, 3.0)
    rt60_s: float = 0.4
    snr_db: float = 10.0
    fs_hz: int = 16000
    ism_order: int | None = 10

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
        return float(self.audio.shape[1] / self.fs_hz)

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
    image-source model can represent movement; silent pieces are skipped and positions
    (rounded to 1 cm) share one response. All responses come from one ``compute_rir`` call.

    Returns
    -------
    Recording, audio shape (n_mics, n_samples) with n_samples the longest talker signal.
    """
    import pyroomacoustics as pra  # heavy imports; only simulations need them
    from scipy import signal

    fs = settings.fs_hz
    mics_room = placement.to_room(array.positions_m)
    size = np.array(settings.size_m)
    if np.any(mics_room < 0.01) or np.any(mics_room > size - 0.01):
        raise ConfigError("array lies outside the room")
    absorption, max_order = pra.inverse_sabine(settings.rt60_s, list(settings.size_m))
    hybrid = settings.ism_order is not None and settings.ism_order < max_order
    if hybrid:
        max_order = settings.ism_order
    room = pra.ShoeBox(list(settings.size_m), fs=fs, materials=pra.Material(absorption),
                       max_order=max_order)
    room.add_microphone_array(mics_room.T)
    n_samples = max(t.samples.size for t in talkers)
    hop = int(round(segment_s * fs))
    fade = np.hanning(2 * hop + 1)[:-1]  # overlapping halves sum to one
    sources: dict[tuple[float, ...], int] = {}
    pieces: list[tuple[int, int, FloatArray]] = []  # (source, offset, samples)

    def source_at(position: FloatArray) -> int:
        key = tuple(np.round(np.clip(position, 0.05, size - 0.05), 2))
        if key not in sources:
            sources[key] = len(sources)
            room.add_source(np.array(key))
        return sources[key]

    for talker in talkers:
        if not talker.moves:
            pieces.append((source_at(talker.path_m[0]), 0, talker.samples))
            continue
        samples = talker.samples
        for start in range(-hop, samples.size, hop):
            lo, hi = max(start, 0), min(start + 2 * hop, samples.size)
            piece = samples[lo:hi] * fade[lo - start : hi - start]
            if hi > lo and np.any(piece):  # silent stretches need no room response
                position = talker.position_at(np.array([(start + hop) / fs]))[0]
                pieces.append((source_at(position), lo, piece))
    room.compute_rir()
    rng = np.random.default_rng(seed + 7919)
    rirs: list[list[FloatArray]] = [[np.asarray(room.rir[m][k]) for m in range(array.n_mics)]
                                    for k in range(len(sources))]
    if hybrid:
        rirs = [with_late_tail(list(r), mics_room, settings, rng) for r in rirs]
    rir_len = max(len(r[m]) for r in rirs for m in range(array.n_mics))
    audio = np.zeros((array.n_mics, n_samples + rir_len))
    for source, offset, piece in pieces:
        for m in range(array.n_mics):
            out = signal.oaconvolve(piece, rirs[source][m])
            audio[m, offset : offset + out.size] += out
    audio = audio[:, :n_samples]
    audio = _add_noise(audio, talkers, settings.snr_db, np.random.default_rng(seed))
    return Recording(audio, fs, tuple(talkers), placement, settings)


def late_tail(mics_m: FloatArray, n_samples: int, fs_hz: int, rng: np.random.Generator,
              n_waves: int = 48) -> FloatArray:
    """Diffuse noise at the mics: white noise arriving from ``n_waves`` random directions.

    Sums of plane waves from directions spread over the sphere give the inter-mic coherence
    of a diffuse field (sinc(2 pi f d / c)), which independent noise per mic would not.

    Returns
    -------
    ndarray, shape (n_mics, n_samples), unit power per mic
    """
    from tracker.units import SPEED_OF_SOUND_M_PER_S

    directions = rng.standard_normal((n_waves, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    n_fft = n_samples + 64
    freqs = np.fft.rfftfreq(n_fft, 1.0 / fs_hz)
    spectra = np.fft.rfft(rng.standard_normal((n_waves, n_fft)), axis=1)  # (K, F)
    advance_s = directions @ (mics_m - mics_m.mean(axis=0)).T / SPEED_OF_SOUND_M_PER_S  # (K, M)
    phase = np.exp(2j * np.pi * advance_s[:, :, None] * freqs[None, None, :])
    tail = np.fft.irfft(np.einsum("kf,kmf->mf", spectra, phase), n_fft, axis=1)[:, 32:32 + n_samples]
    return np.asarray(tail / np.sqrt(np.mean(tail**2)))


def with_late_tail(rirs: list[FloatArray], mics_m: FloatArray, settings: RoomSettings,
                   rng: np.random.Generator, mix_after_s: float = 0.06, fade_s: float = 0.02
                   ) -> list[FloatArray]:
    """Replace the truncated image-source tail by a diffuse exponential decay.

    From ``mix_after_s`` after the direct sound the responses cross-fade (over ``fade_s``)
    into :func:`late_tail` shaped by ``exp(-6.91 t / RT60)`` (60 dB of energy in RT60), its
    level matched to the image-source energy in the 20 ms before the mix point.
    """
    fs = settings.fs_hz
    length = max(len(r) for r in rirs)
    direct = min(int(np.argmax(np.abs(r))) for r in rirs)
    mix = direct + int(mix_after_s * fs)
    fade = int(fade_s * fs)
    total = max(length, mix + fade + int(1.2 * settings.rt60_s * fs))
    padded = np.zeros((len(rirs), total))
    for m, r in enumerate(rirs):
        padded[m, : len(r)] = r
    t = (np.arange(total) - mix) / fs
    decay = np.exp(-6.91 * t / settings.rt60_s)
    ref = slice(max(direct + 1, mix - int(0.02 * fs)), mix)
    level = np.sqrt(np.mean(padded[:, ref] ** 2) / np.mean(decay[ref] ** 2))
    tail = late_tail(mics_m, total, fs, rng) * decay * level
    ramp = np.clip((np.arange(total) - mix) / max(fade, 1), 0.0, 1.0)
    return list(padded * (1.0 - ramp) + tail * ramp)


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
    return np.asarray(point, dtype=float)
