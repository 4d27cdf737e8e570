"""Talker tracking on steered-response maps: a grid Bayes filter over azimuth and bearing rate.

Instead of a peak per window, every short window's whole steered-response map (SRP-PHAT over
a 1° azimuth grid) is evidence (track-before-detect): a reflection that wins one window's
peak hardly moves a posterior that the direct path has fed for several windows.

The filter (an HMM on a grid; Stone et al., *Bayesian Multiple Target Tracking*, ch. 3):

* state: azimuth cell × bearing rate from a bank ``rates_rad_s``; each rate row is shifted by
  ``rate * dt`` every frame and blurred by ``diffusion_rad_per_sqrt_s * sqrt(dt)``; old
  evidence fades (the log-posterior is multiplied by ``exp(-dt / forget_tau_s)``);
* rate changes: each frame a share ``rate_mixing`` of the mass is redrawn from the rate
  prior, which puts ``static_prior`` on "not moving"; after ``coast_s`` without speech all
  of it is (a walker stops between turns);
* talker changes: each speech frame a share ``birth_share`` of the mass is redrawn from the
  birth prior over azimuth, uniform plus ``memory_share`` on the remembered seats of still
  talkers (``memory_std_rad`` wide, forgotten after ``memory_s``): a talker seen before
  is picked up after fewer windows;
* measurement: ``likelihood = floor + exp(sharpness * (p - max p))`` of the window's map ``p``
  (``likelihood_floor`` makes a burst of reflections one bounded factor, not a veto);
  windows the speech detector rejected count with ``unvoiced_weight`` times the sharpness,
  for the current talker only (quiet syllables; a cough far from her moves nothing).

The camera-operator policy on the posterior (every setting in :class:`MapTrackerSettings`):

* the current talker's position is the posterior peak within ``gate_rad`` of her last one,
  moving at most ``max_rate_rad_s``; her bearing rate is the least-squares slope of her
  positions over the last ``rate_window_s`` (the bank's rate posterior is too timid);
* a new talker (posterior mass ``switch_mass`` within ``gate_rad`` of a peak outside the
  current talker's gate) must keep it for ``reaction_time_s`` before the camera goes there,
  and not within ``min_hold_s`` of the last switch unless the floor was silent for
  ``pause_tolerance_s``; a peak within ``reacquire_rad`` is the same talker found again
  (the track restarts there; not a switch);
* the shot moves when the talker leaves the ``deadband_rad`` around it; a talker faster than
  ``moving_rate_rad_s`` is followed in ``moving_deadband_rad`` steps, led by ``rate * lead_s``;
* ``wide_after_switches`` switches back and forth between the same two directions within
  ``wide_window_s`` give a wide shot between them until one talker holds the floor for
  ``wide_release_s``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from tracker.audio.tracking import TrackPoint
from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]


def _wrap(angle_rad: float) -> float:
    """Wrap into (-pi, pi]."""
    return float(-((-angle_rad + np.pi) % (2 * np.pi) - np.pi))


@dataclass(frozen=True, slots=True)
class MapTrackerSettings:
    """Grid filter and camera policy of :class:`MapTracker`; every field adjustable."""

    sharpness: float = 20.0
    forget_tau_s: float = 1.0
    likelihood_floor: float = 0.02
    unvoiced_weight: float = 0.5
    rates_rad_s: tuple[float, ...] = tuple(float(v) for v in np.deg2rad(np.arange(-12.0, 13.0, 2.0)))
    static_prior: float = 0.8
    rate_mixing: float = 0.05
    diffusion_rad_per_sqrt_s: float = float(np.deg2rad(1.5))
    birth_share: float = 0.2
    memory_share: float = 0.5
    memory_std_rad: float = float(np.deg2rad(3.0))
    memory_s: float = 300.0
    coast_s: float = 1.2
    gate_rad: float = float(np.deg2rad(8.0))
    switch_mass: float = 0.5
    moving_mass: float = 0.6
    reaction_time_s: float = 0.1
    min_hold_s: float = 2.0
    pause_tolerance_s: float = 1.5
    reacquire_rad: float = float(np.deg2rad(20.0))
    deadband_rad: float = float(np.deg2rad(3.0))
    moving_rate_rad_s: float = float(np.deg2rad(4.0))
    moving_deadband_rad: float = float(np.deg2rad(1.0))
    lead_s: float = 0.3
    rate_window_s: float = 1.5
    max_rate_rad_s: float = float(np.deg2rad(25.0))
    wide_after_switches: int = 4
    wide_window_s: float = 20.0
    wide_release_s: float = 6.0
    wide_azimuth_rad: float | None = None

    def __post_init__(self) -> None:
        for name in ("sharpness", "forget_tau_s", "likelihood_floor", "unvoiced_weight",
                     "diffusion_rad_per_sqrt_s", "memory_std_rad", "memory_s", "coast_s",
                     "gate_rad", "reaction_time_s", "min_hold_s", "pause_tolerance_s",
                     "reacquire_rad", "deadband_rad", "moving_rate_rad_s", "moving_deadband_rad",
                     "lead_s", "rate_window_s", "max_rate_rad_s", "wide_window_s",
                     "wide_release_s"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise ConfigError(f"map tracker setting {name}={value} must be a finite value >= 0")
        for name in ("static_prior", "rate_mixing", "birth_share", "memory_share", "switch_mass",
                     "moving_mass"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ConfigError(f"map tracker setting {name}={value} must be within 0-1")
        if not self.rates_rad_s or 0.0 not in self.rates_rad_s:
            raise ConfigError(f"rates_rad_s={self.rates_rad_s} must include 0 (a seated talker)")
        if self.wide_after_switches < 2:
            raise ConfigError(f"wide_after_switches={self.wide_after_switches} must be >= 2")
        if self.memory_std_rad <= 0 or self.gate_rad <= 0:
            raise ConfigError("memory_std_rad and gate_rad must be > 0")


@dataclass(slots=True)
class MapTracker:
    """Feed each window's map with :meth:`step`; see the module docstring.

    Parameters
    ----------
    azimuth_rad : ndarray, shape (n_map,)
        The maps' azimuth grid, evenly spaced and increasing.
    settings : MapTrackerSettings
    """

    azimuth_rad: FloatArray
    settings: MapTrackerSettings = field(default_factory=MapTrackerSettings)
    _posterior: FloatArray = field(init=False)
    _rate_prior: FloatArray = field(init=False)
    _rates: FloatArray = field(init=False)
    _step_rad: float = field(init=False)
    _t_s: float | None = None
    _last_speech_t_s: float = -np.inf
    _talker_rad: float | None = None
    _talker_rate_rad_s: float = 0.0
    _elevation_rad: float | None = None
    _target_rad: float = 0.0
    _candidate: tuple[float, float] | None = None  # (since t_s, azimuth_rad)
    _last_switch_t_s: float = -np.inf
    _switches: list[tuple[float, float, float]] = field(default_factory=list)
    _wide_rad: float | None = None
    _seats: list[tuple[float, float]] = field(default_factory=list)  # (azimuth_rad, last t_s)
    _history: list[tuple[float, float]] = field(default_factory=list)  # (t_s, talker azimuth_rad)

    def __post_init__(self) -> None:
        az = np.asarray(self.azimuth_rad, dtype=float)
        steps = np.diff(az)
        if az.ndim != 1 or az.size < 3 or not np.allclose(steps, steps[0]) or steps[0] <= 0:
            raise ConfigError("map azimuth grid must be 1-D, evenly spaced and increasing "
                              f"(got {az.size} points)")
        self.azimuth_rad = az
        self._step_rad = float(steps[0])
        s = self.settings
        self._rates = np.asarray(s.rates_rad_s, dtype=float)
        moving = self._rates != 0.0
        prior = np.where(moving, (1.0 - s.static_prior) / max(1, int(moving.sum())), s.static_prior)
        self._rate_prior = prior / prior.sum()
        self._posterior = self._rate_prior[:, None] * np.full(az.size, 1.0 / az.size)[None, :]

    # -- the grid filter -------------------------------------------------------------------

    def step(self, t_s: float, power_map: FloatArray, elevation_rad: float | None,
             speech: bool) -> TrackPoint:
        """Take one window's map (time order), shape (n_map,); return the camera target."""
        p = np.asarray(power_map, dtype=float)
        if p.shape != self.azimuth_rad.shape:
            raise DataError(f"map at t={t_s:.3f} s has shape {p.shape}, grid has "
                            f"{self.azimuth_rad.shape}")
        dt = 0.0 if self._t_s is None else max(0.0, t_s - self._t_s)
        self._t_s = t_s
        moving = t_s - self._last_speech_t_s <= self.settings.coast_s
        self._predict(dt, moving)
        if not np.all(np.isfinite(p)):
            return self._target(t_s)
        if speech:
            floor_open = t_s - self._last_speech_t_s > self.settings.pause_tolerance_s
            if t_s - self._last_speech_t_s > self.settings.coast_s:
                self._history = []  # a talker who paused is not still walking
            self._update(t_s, p, self.settings.sharpness)
            self._decide(t_s, elevation_rad, floor_open)
            self._last_speech_t_s = t_s
        elif moving and self.settings.unvoiced_weight > 0.0 and self._talker_rad is not None:
            # Within a turn, windows the speech detector rejected (quiet syllables) still
            # count, weakly, for the current talker; they never start a switch.
            self._update(t_s, p, self.settings.unvoiced_weight * self.settings.sharpness, birth=False)
            mass, mean = self._mass_near(self.marginal(), self._talker_rad)
            if mass >= 0.5 * self.settings.switch_mass:
                self._follow(t_s, mean, elevation_rad)
        return self._target(t_s)

    def _predict(self, dt: float, moving: bool) -> None:
        s, post = self.settings, self._posterior
        if dt <= 0.0:
            return
        if moving:
            shifted = np.empty_like(post)
            for k, rate in enumerate(self._rates):
                shifted[k] = _shift(post[k], rate * dt / self._step_rad)
            post = shifted
            mix = 1.0 - (1.0 - s.rate_mixing) ** (dt / 0.1)
        else:  # pause: the walker stops, every hypothesis falls back to the rate prior
            mix = 1.0
        if s.forget_tau_s > 0.0:  # old evidence fades: log-posterior decays with forget_tau_s
            post = np.maximum(post, 1e-300) ** np.exp(-dt / s.forget_tau_s)
            post = post / post.sum()
        marginal = post.sum(axis=0)
        post = (1.0 - mix) * post + mix * self._rate_prior[:, None] * marginal[None, :]
        sigma = s.diffusion_rad_per_sqrt_s * np.sqrt(dt) / self._step_rad
        if sigma > 1e-3:
            post = gaussian_filter1d(post, sigma, axis=1, mode="nearest")
        self._posterior = post / post.sum()

    def _update(self, t_s: float, p: FloatArray, sharpness: float, birth: bool = True) -> None:
        s = self.settings
        post = self._posterior
        if birth:
            post = (1.0 - s.birth_share) * post + s.birth_share * (
                self._rate_prior[:, None] * self._birth_prior(t_s)[None, :])
        likelihood = s.likelihood_floor + np.exp(sharpness * (p - p.max()))
        post = post * likelihood[None, :]
        self._posterior = post / post.sum()

    def _birth_prior(self, t_s: float) -> FloatArray:
        """Uniform over azimuth plus ``memory_share`` on the remembered seats; sums to 1."""
        s, az = self.settings, self.azimuth_rad
        uniform = np.full(az.size, 1.0 / az.size)
        self._seats = [seat for seat in self._seats if t_s - seat[1] <= s.memory_s]
        if not self._seats or s.memory_share <= 0.0:
            return uniform
        bumps = sum(np.exp(-0.5 * ((az - a) / s.memory_std_rad) ** 2) for a, _ in self._seats)
        bumps = np.asarray(bumps) / np.sum(bumps)
        return np.asarray((1.0 - s.memory_share) * uniform + s.memory_share * bumps)

    def marginal(self) -> FloatArray:
        """Posterior probability of each azimuth cell (rates summed); shape (n_map,)."""
        return np.asarray(self._posterior.sum(axis=0))

    # -- the camera operator ---------------------------------------------------------------

    def _mass_near(self, marginal: FloatArray, centre_rad: float) -> tuple[float, float]:
        """Posterior mass within the gate of ``centre_rad`` and the local peak there.

        The peak is refined by a parabola through the best cell and its neighbours.
        """
        near = np.flatnonzero(np.abs(self.azimuth_rad - centre_rad) <= self.settings.gate_rad)
        mass = float(marginal[near].sum())
        if mass <= 0.0:
            return 0.0, centre_rad
        k = int(near[np.argmax(marginal[near])])
        if 0 < k < marginal.size - 1:
            lo, mid, hi = np.log(np.maximum(marginal[k - 1 : k + 2], 1e-300))
            curvature = lo - 2.0 * mid + hi
            offset = 0.5 * (lo - hi) / curvature if curvature < 0 else 0.0
            return mass, float(self.azimuth_rad[k] + np.clip(offset, -0.5, 0.5) * self._step_rad)
        return mass, float(self.azimuth_rad[k])

    def _decide(self, t_s: float, elevation_rad: float | None, floor_open: bool) -> None:
        s = self.settings
        marginal = self.marginal()
        peak = float(self.azimuth_rad[int(np.argmax(marginal))])
        peak_mass, peak_mean = self._mass_near(marginal, peak)
        if self._talker_rad is not None:
            mass, mean = self._mass_near(marginal, self._talker_rad)
            if mass >= 0.5 * s.switch_mass or abs(peak - self._talker_rad) <= s.gate_rad:
                self._follow(t_s, mean, elevation_rad)
                self._candidate = None
                return
        if peak_mass < s.switch_mass:
            self._candidate = None
            return
        if self._candidate is None or abs(self._candidate[1] - peak_mean) > s.gate_rad:
            self._candidate = (t_s, peak_mean)
            if s.reaction_time_s > 0.0:
                return
        self._candidate = (self._candidate[0], peak_mean)
        if t_s - self._candidate[0] < s.reaction_time_s - 1e-9:
            return
        current = self._talker_rad
        if current is not None and abs(peak_mean - current) <= s.reacquire_rad:
            self._start_talker(t_s, peak_mean, elevation_rad)  # the same talker found again
            return
        if current is None or floor_open or t_s - self._last_switch_t_s >= s.min_hold_s:
            self._start_talker(t_s, peak_mean, elevation_rad)
            if current is not None:
                self._last_switch_t_s = t_s
                self._switches.append((t_s, current, peak_mean))
                self._update_wide(t_s)

    def _follow(self, t_s: float, azimuth_rad: float, elevation_rad: float | None) -> None:
        """Move the current talker towards the local posterior peak (at most ``max_rate_rad_s``
        since her last evidence); learn her rate and seat."""
        s = self.settings
        if self._talker_rad is not None and self._history:
            reach = s.max_rate_rad_s * (t_s - self._history[-1][0]) + self._step_rad
            azimuth_rad = self._talker_rad + float(np.clip(azimuth_rad - self._talker_rad, -reach, reach))
        self._talker_rad = azimuth_rad
        near = np.abs(self.azimuth_rad - azimuth_rad) <= s.gate_rad
        by_rate = self._posterior[:, near].sum(axis=1)
        total = float(by_rate.sum())
        moving_share = float(by_rate[self._rates != 0.0].sum()) / max(total, 1e-300)
        if moving_share < s.moving_mass:
            self._remember(t_s, azimuth_rad)
        self._history = [h for h in self._history if t_s - h[0] <= s.rate_window_s]
        self._history.append((t_s, azimuth_rad))
        self._talker_rate_rad_s = self._history_rate()
        if elevation_rad is not None:
            self._elevation_rad = elevation_rad if self._elevation_rad is None else (
                self._elevation_rad + 0.2 * (elevation_rad - self._elevation_rad))

    def _history_rate(self) -> float:
        """Least-squares bearing rate of the talker's last ``rate_window_s`` (0 when too short)."""
        if len(self._history) < 4 or self._history[-1][0] - self._history[0][0] < 0.5 * (
                self.settings.rate_window_s):
            return 0.0
        t, a = np.array(self._history).T
        t = t - t.mean()
        return float(t @ (a - a.mean()) / (t @ t))

    def _remember(self, t_s: float, azimuth_rad: float) -> None:
        """A still talker's seat (merged with a remembered one within the gate)."""
        s = self.settings
        for k, (a, _) in enumerate(self._seats):
            if abs(a - azimuth_rad) <= s.gate_rad:
                self._seats[k] = (a + 0.1 * (azimuth_rad - a), t_s)
                return
        self._seats.append((azimuth_rad, t_s))

    def _start_talker(self, t_s: float, azimuth_rad: float, elevation_rad: float | None) -> None:
        self._talker_rad = azimuth_rad
        self._talker_rate_rad_s = 0.0
        self._history = [(t_s, azimuth_rad)]
        self._elevation_rad = elevation_rad
        self._target_rad = azimuth_rad
        self._candidate = None

    def _update_wide(self, t_s: float) -> None:
        """Go wide after repeated switching between the same two directions."""
        s = self.settings
        self._switches = [sw for sw in self._switches if t_s - sw[0] <= s.wide_window_s]
        if len(self._switches) < s.wide_after_switches:
            return
        a, b = self._switches[-1][1], self._switches[-1][2]
        ends = [x for sw in self._switches for x in sw[1:]]
        if all(min(abs(_wrap(x - a)), abs(_wrap(x - b))) <= s.gate_rad for x in ends):
            mid = float(np.angle(np.exp(1j * a) + np.exp(1j * b)))
            self._wide_rad = s.wide_azimuth_rad if s.wide_azimuth_rad is not None else mid

    def _target(self, t_s: float) -> TrackPoint:
        s = self.settings
        talker = self._talker_rad
        if talker is None:
            return TrackPoint(t_s, self._target_rad, self._elevation_rad, "none", None)
        if self._wide_rad is not None:
            if t_s - self._last_switch_t_s < s.wide_release_s:
                return TrackPoint(t_s, self._wide_rad, None, "wide", talker)
            self._wide_rad = None
            self._switches.clear()
            self._target_rad = talker
        rate = self._talker_rate_rad_s
        if abs(rate) >= s.moving_rate_rad_s:
            ahead = talker + rate * s.lead_s
            if abs(ahead - self._target_rad) > s.moving_deadband_rad:
                self._target_rad = ahead
        elif abs(talker - self._target_rad) > s.deadband_rad:
            self._target_rad = talker
        return TrackPoint(t_s, self._target_rad, self._elevation_rad, "talker", talker)


def _shift(row: FloatArray, cells: float) -> FloatArray:
    """``row`` moved by a fractional number of cells (linear interpolation; the edges hold)."""
    index = np.arange(row.size, dtype=float) - cells
    return np.asarray(np.interp(index, np.arange(row.size, dtype=float), row))
