"""Talker tracking on steered-response maps: a grid Bayes filter over azimuth and bearing rate.

Each short window's whole SRP-PHAT map (1° azimuth grid) is evidence (track-before-detect): a
reflection that wins one window's peak hardly moves a posterior the direct path has fed for
several windows. The filter (an HMM on a grid; Stone et al., *Bayesian Multiple Target
Tracking*, ch. 3), every setting in :class:`MapTrackerSettings`:

* state: azimuth × bearing rate (bank ``rates_rad_s``): rows shift by ``rate * dt``, blur by
  ``diffusion_rad_per_sqrt_s``; the log-posterior fades with ``forget_tau_s``; a share
  ``rate_mixing`` per frame is redrawn from the rate prior (``static_prior`` on "still"),
  all of it after ``coast_s`` of silence; near a talker who walks (this turn, or her track's
  rate over ``moving_rate_rad_s``) a share ``walker_mix`` per 0.1 s is redrawn instead around her
  track's rate (Gaussian, ``walker_rate_std_rad_s``): she keeps walking, and the still-biased
  prior no longer holds her posterior behind her;
* births: per speech window a share ``birth_share`` is redrawn over azimuth, uniform plus
  ``memory_share`` on seats (median of a still talker's last positions, ``memory_std_rad``,
  kept ``memory_s``): known talkers are found sooner, a seated talker's seat steadies her
  track; a talker who walked this turn loses hers;
* likelihood ``likelihood_floor + exp(sharpness * w * (p - max p))``; ``w`` is the window's
  confidence over the recent median, to the ``confidence_power`` (reverberant windows count
  less); windows the speech detector rejected weigh ``unvoiced_weight`` times that (quiet
  syllables; a turn's first ones with ``unvoiced_births``) and never decide a switch.

The camera operator: the talker is the posterior peak within ``gate_rad`` of her track (moving
at most ``max_rate_rad_s``), her rate the slope of her last ``rate_window_s``. A new talker
(mass ``switch_mass`` within the gate of a peak outside hers) is taken at once when heard within
``onset_s`` of speech resuming after ``turn_gap_s`` of silence (a turn change), after
``reaction_time_s`` when she cuts in mid-speech (or is a reflection); never within
``min_hold_s`` of the last switch unless the floor was silent ``pause_tolerance_s``; within
``reacquire_rad`` of the track she is the same talker found again (no switch). The shot moves
when she leaves ``deadband_rad`` (``moving_deadband_rad`` above ``moving_rate_rad_s``, led by
``rate * lead_s``); ``wide_after_switches`` switches between two directions within
``wide_window_s`` give a wide shot between them until one holds the floor ``wide_release_s``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from tracker.audio.filters import gaussian_blur
from tracker.audio.tracking import TrackPoint, WindowVotes, back_and_forth_midpoint
from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class MapTrackerSettings:
    """Grid filter and camera policy of :class:`MapTracker`; every field adjustable."""

    sharpness: float = 20.0
    forget_tau_s: float = 1.5
    likelihood_floor: float = 0.02
    unvoiced_weight: float = 0.5
    unvoiced_births: bool = True
    confidence_power: float = 2.0
    confidence_window_s: float = 10.0
    rates_rad_s: tuple[float, ...] = tuple(float(v) for v in np.deg2rad(np.arange(-12.0, 13.0, 2.0)))
    static_prior: float = 0.8
    rate_mixing: float = 0.01
    diffusion_rad_per_sqrt_s: float = float(np.deg2rad(1.5))
    birth_share: float = 0.2
    memory_share: float = 0.5
    memory_std_rad: float = float(np.deg2rad(3.0))
    memory_s: float = 300.0
    coast_s: float = 1.2
    gate_rad: float = float(np.deg2rad(8.0))
    switch_mass: float = 0.5
    reaction_time_s: float = 0.2
    turn_gap_s: float = 0.25
    onset_s: float = 0.5
    min_hold_s: float = 2.0
    pause_tolerance_s: float = 1.5
    reacquire_rad: float = float(np.deg2rad(20.0))
    deadband_rad: float = float(np.deg2rad(3.0))
    moving_rate_rad_s: float = float(np.deg2rad(4.0))
    moving_deadband_rad: float = float(np.deg2rad(1.0))
    lead_s: float = 0.3
    rate_window_s: float = 1.75
    max_rate_rad_s: float = float(np.deg2rad(25.0))
    walker_mix: float = 0.1
    walker_rate_std_rad_s: float = float(np.deg2rad(3.0))
    wide_after_switches: int = 4
    wide_window_s: float = 20.0
    wide_release_s: float = 6.0
    wide_azimuth_rad: float | None = None
    majority_guard: bool = True

    def __post_init__(self) -> None:
        fractions = ("static_prior", "rate_mixing", "birth_share", "memory_share", "switch_mass",
                     "walker_mix")
        for name in self.__slots__:
            value = getattr(self, name)
            if name in fractions and not 0.0 <= value <= 1.0:
                raise ConfigError(f"map tracker setting {name}={value} must be within 0-1")
            if isinstance(value, float) and name != "wide_azimuth_rad" and not (
                    np.isfinite(value) and value >= 0.0):
                raise ConfigError(f"map tracker setting {name}={value} must be a finite value >= 0")
        if not self.rates_rad_s or 0.0 not in self.rates_rad_s:
            raise ConfigError(f"rates_rad_s={self.rates_rad_s} must include 0 (a seated talker)")
        if self.wide_after_switches < 2:
            raise ConfigError(f"wide_after_switches={self.wide_after_switches} must be >= 2")
        if self.memory_std_rad <= 0 or self.gate_rad <= 0:
            raise ConfigError("memory_std_rad and gate_rad must be > 0")


_SEAT_POSITIONS = 30  # positions a seat keeps (it sits at their median)


@dataclass(slots=True)
class _Seat:
    """Where a still talker was: the median of her recent tracked positions."""

    positions_rad: list[float]
    last_t_s: float
    circular: bool = False  # positions are kept on the first one's turn; the median is wrapped
    azimuth_rad: float = field(init=False)  # the median of positions_rad

    def __post_init__(self) -> None:
        self.azimuth_rad = self._median()

    def _median(self) -> float:
        # np.median's value (the middle one, or the mean of the two middle ones), without its
        # overhead on a short list.
        ordered, n = sorted(self.positions_rad), len(self.positions_rad)
        median = ordered[n // 2] if n % 2 else (ordered[n // 2 - 1] + ordered[n // 2]) / 2
        return _wrap(median) if self.circular else median

    def add(self, t_s: float, azimuth_rad: float) -> None:
        """Another tracked position (the oldest beyond the last ``_SEAT_POSITIONS`` is dropped)."""
        if self.circular:  # on the turn of the seat's positions
            azimuth_rad = self.positions_rad[-1] + _wrap(azimuth_rad - self.positions_rad[-1])
        self.positions_rad = [*self.positions_rad[-(_SEAT_POSITIONS - 1):], azimuth_rad]
        self.azimuth_rad = self._median()
        self.last_t_s = t_s


@dataclass(slots=True)
class MapTracker:
    """Feed each window's map with :meth:`step`; see the module docstring.

    Parameters
    ----------
    azimuth_rad : ndarray, shape (n_map,)
        The maps' azimuth grid, evenly spaced and increasing.
    settings : MapTrackerSettings
    circular : bool
        The grid is the full circle (``n_map`` steps make a turn): it wraps at ±180°, so a
        talker walking behind the array is followed across it (an array on a table or the
        ceiling). Otherwise it is a line whose ends are the field of view's edges, which the
        shots never leave.
    """

    azimuth_rad: FloatArray
    settings: MapTrackerSettings = field(default_factory=MapTrackerSettings)
    circular: bool = False
    _posterior: FloatArray = field(init=False)
    _rate_prior: FloatArray = field(init=False)
    _rates: FloatArray = field(init=False)
    _step_rad: float = field(init=False)
    _t_s: float | None = None
    _last_speech_t_s: float = -np.inf
    _speech_run_t_s: float = -np.inf  # when speech resumed after a gap of turn_gap_s
    _talker_rad: float | None = None
    _talker_rate_rad_s: float = 0.0
    _elevation_rad: float | None = None
    _target_rad: float = 0.0
    _candidate: tuple[float, float] | None = None  # (since t_s, azimuth_rad)
    _last_switch_t_s: float = -np.inf
    _switches: list[tuple[float, float, float]] = field(default_factory=list)
    _wide_rad: float | None = None
    _seats: list[_Seat] = field(default_factory=list)
    _history: list[tuple[float, float]] = field(default_factory=list)  # (t_s, talker azimuth_rad)
    _walked: bool = False  # the current talker has walked during this turn
    _confidences: list[tuple[float, float]] = field(default_factory=list)  # speech windows'
    _sorted_confidences: list[float] = field(default_factory=list)  # the same, sorted
    _votes: WindowVotes = field(init=False)  # speech windows' map peaks
    _birth_cache: tuple[tuple[float, ...], FloatArray] | None = None  # seats -> birth prior

    def __post_init__(self) -> None:
        az = np.asarray(self.azimuth_rad, dtype=float)
        steps = np.diff(az)
        if az.ndim != 1 or az.size < 3 or not np.allclose(steps, steps[0]) or steps[0] <= 0:
            raise ConfigError("map azimuth grid must be 1-D, evenly spaced and increasing "
                              f"(got {az.size} points)")
        self.azimuth_rad = az
        self._step_rad = float(steps[0])
        if self.circular and abs(az.size * self._step_rad - 2.0 * np.pi) > 1e-6:
            raise ConfigError(f"a circular map grid must make a full turn ({az.size} cells of "
                              f"{np.rad2deg(self._step_rad):.3f}° do not)")
        s = self.settings
        self._votes = WindowVotes(s.gate_rad)
        self._rates = np.asarray(s.rates_rad_s, dtype=float)
        moving = self._rates != 0.0
        prior = np.where(moving, (1.0 - s.static_prior) / max(1, int(moving.sum())), s.static_prior)
        self._rate_prior = prior / prior.sum()
        self._posterior = self._rate_prior[:, None] * np.full(az.size, 1.0 / az.size)[None, :]

    # -- the grid filter -------------------------------------------------------------------

    def step(self, t_s: float, power_map: FloatArray, elevation_rad: float | None,
             speech: bool, confidence: float = 1.0) -> TrackPoint:
        """Take one window's map (time order), shape (n_map,), and the localizer's confidence
        for it; return the camera target."""
        p, s = np.asarray(power_map, dtype=float), self.settings
        if p.shape != self.azimuth_rad.shape:
            raise DataError(f"map at t={t_s:.3f} s has shape {p.shape}, grid has "
                            f"{self.azimuth_rad.shape}")
        self._predict(0.0 if self._t_s is None else max(0.0, t_s - self._t_s),
                      moving := t_s - self._last_speech_t_s <= s.coast_s)
        self._t_s = t_s
        gap = t_s - self._last_speech_t_s
        if speech and np.all(np.isfinite(p)):
            self._speech_run_t_s = t_s if gap > s.turn_gap_s else self._speech_run_t_s
            if gap > s.coast_s:  # a talker who paused is not still walking
                self._history, self._walked = [], False
            self._votes.add(t_s, float(self.azimuth_rad[int(np.argmax(p))]))
            self._update(t_s, p, s.sharpness * self._weight(t_s, confidence))
            self._decide(t_s, elevation_rad, floor_open=gap > s.pause_tolerance_s)
            self._last_speech_t_s = t_s
        elif np.all(np.isfinite(p)) and s.unvoiced_weight > 0.0 and (
                s.unvoiced_births or (moving and self._talker_rad is not None)):
            # Rejected windows count weakly (quiet syllables, a turn's onset), never decide.
            weight = s.unvoiced_weight * self._weight(t_s, confidence, keep=False)
            self._update(t_s, p, weight * s.sharpness, birth=s.unvoiced_births)
            if moving and self._talker_rad is not None:
                mass, peak = self._mass_near(self.marginal(), self._talker_rad)
                if mass >= 0.5 * s.switch_mass:
                    self._follow(t_s, peak, elevation_rad)
        return self._target(t_s)

    def _weight(self, t_s: float, confidence: float, keep: bool = True) -> float:
        """A window's weight: its confidence over recent speech windows' median (``keep``: a
        speech window, one of them), to the ``confidence_power``."""
        s = self.settings
        while self._confidences and t_s - self._confidences[0][0] > s.confidence_window_s:
            _, old = self._confidences.pop(0)
            del self._sorted_confidences[bisect.bisect_left(self._sorted_confidences, old)]
        if keep or not self._confidences:
            self._confidences.append((t_s, confidence))
            bisect.insort(self._sorted_confidences, confidence)
        values, n = self._sorted_confidences, len(self._sorted_confidences)
        # np.median of the window's confidences, from the kept sorted copy
        median = values[n // 2] if n % 2 else (values[n // 2 - 1] + values[n // 2]) / 2
        if s.confidence_power <= 0.0 or median <= 0.0:
            return 1.0
        return float(min(max(confidence / median, 0.0), 3.0) ** s.confidence_power)

    def _predict(self, dt: float, moving: bool) -> None:
        s, post = self.settings, self._posterior
        if dt <= 0.0:
            return
        if moving:
            post = _shift_rows(post, self._rates * dt / self._step_rad, self.circular)
            mix = 1.0 - (1.0 - s.rate_mixing) ** (dt / 0.1)
        else:  # pause: the walker stops, every hypothesis falls back to the rate prior
            mix = 1.0
        if s.forget_tau_s > 0.0:  # old evidence fades: log-posterior decays with forget_tau_s
            post = np.maximum(post, 1e-300) ** np.exp(-dt / s.forget_tau_s)
            post = post / post.sum()
        if moving:
            post = self._keep_walking(post, dt)
        marginal = post.sum(axis=0)
        post = (1.0 - mix) * post + mix * self._rate_prior[:, None] * marginal[None, :]
        sigma = s.diffusion_rad_per_sqrt_s * np.sqrt(dt) / self._step_rad
        if sigma > 1e-3:
            post = gaussian_blur(post, sigma, wrap=self.circular)
        self._posterior = post / post.sum()

    def _keep_walking(self, post: FloatArray, dt: float) -> FloatArray:
        """Within two gates of a walking talker, redraw ``walker_mix`` per 0.1 s of the
        posterior over rates around her track's rate (a constant-rate model whose rate
        wanders): the bank's still-biased prior would otherwise hold her track behind her."""
        s, talker, rate = self.settings, self._talker_rad, self._talker_rate_rad_s
        if talker is None or s.walker_mix <= 0.0 or s.walker_rate_std_rad_s <= 0.0 or not (
                self._walked or abs(rate) >= s.moving_rate_rad_s):
            return post
        near = np.abs(self._offset(self.azimuth_rad, talker)) <= 2.0 * s.gate_rad
        own = np.exp(-0.5 * ((self._rates - rate) / s.walker_rate_std_rad_s) ** 2)
        mix = 1.0 - (1.0 - s.walker_mix) ** (dt / 0.1)
        post = post.copy()
        post[:, near] = (1.0 - mix) * post[:, near] + mix * (own / own.sum())[:, None] * (
            post[:, near].sum(axis=0)[None, :])
        return np.asarray(post / post.sum())

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
        self._seats = [seat for seat in self._seats if t_s - seat.last_t_s <= s.memory_s]
        # Seats near a talker who walked this turn are left out: they would hold her back.
        current = self._talker_rad
        seats = [seat.azimuth_rad for seat in self._seats if not self._walked or current is None
                 or abs(self._offset(seat.azimuth_rad, current)) > s.gate_rad]
        if not seats or s.memory_share <= 0.0:
            return uniform
        key = tuple(seats)
        if self._birth_cache is not None and self._birth_cache[0] == key:
            return self._birth_cache[1]  # the seats have not moved since the last window
        bumps = sum(np.exp(-0.5 * (self._offset(az, a) / s.memory_std_rad) ** 2) for a in seats)
        bumps = np.asarray(bumps) / np.sum(bumps)
        prior = np.asarray((1.0 - s.memory_share) * uniform + s.memory_share * bumps)
        self._birth_cache = (key, prior)
        return prior

    def marginal(self) -> FloatArray:
        """Posterior probability of each azimuth cell (rates summed); shape (n_map,)."""
        return np.asarray(self._posterior.sum(axis=0))

    def _offset(self, a: FloatArray | float, b: float) -> FloatArray:
        """``a - b`` (rad), the short way round on a circular grid."""
        d = np.asarray(a, dtype=float) - b
        return np.asarray(np.remainder(d + np.pi, 2.0 * np.pi) - np.pi) if self.circular else d

    def _distance(self, a: float, b: float) -> float:
        """``|a - b|`` (rad), the short way round on a circular grid (Python floats: the same
        values as :meth:`_offset`)."""
        d = float(a) - float(b)
        if self.circular:
            d = (d + math.pi) % (2.0 * math.pi) - math.pi
        return abs(d)

    def _on_grid(self, azimuth_rad: float) -> float:
        """An azimuth wrapped (circular grid) or held between the grid's ends (a line)."""
        if self.circular:
            return _wrap(azimuth_rad)
        return min(max(azimuth_rad, float(self.azimuth_rad[0])), float(self.azimuth_rad[-1]))

    # -- the camera operator ---------------------------------------------------------------

    def _mass_near(self, marginal: FloatArray, centre_rad: float) -> tuple[float, float]:
        """Posterior mass within the gate of ``centre_rad`` and the local peak there (refined
        by a parabola through the best cell and its neighbours)."""
        near = np.flatnonzero(np.abs(self._offset(self.azimuth_rad, centre_rad))
                              <= self.settings.gate_rad)
        mass = float(marginal[near].sum())
        if mass <= 0.0:
            return 0.0, centre_rad
        k = int(near[np.argmax(marginal[near])])
        n = marginal.size
        if 0 < k < n - 1 or self.circular:
            lo, mid, hi = np.log(np.maximum(marginal[[(k - 1) % n, k, (k + 1) % n]], 1e-300))
            curvature = lo - 2.0 * mid + hi
            offset = 0.5 * (lo - hi) / curvature if curvature < 0 else 0.0
            peak = float(self.azimuth_rad[k] + np.clip(offset, -0.5, 0.5) * self._step_rad)
            return mass, _wrap(peak) if self.circular else peak
        return mass, float(self.azimuth_rad[k])

    def _decide(self, t_s: float, elevation_rad: float | None, floor_open: bool) -> None:
        s = self.settings
        marginal = self.marginal()
        peak = float(self.azimuth_rad[int(np.argmax(marginal))])
        peak_mass, peak_at = self._mass_near(marginal, peak)
        current = self._talker_rad
        if current is not None:
            mass, local = self._mass_near(marginal, current)
            if mass >= 0.5 * s.switch_mass or self._distance(peak, current) <= s.gate_rad:
                self._follow(t_s, local, elevation_rad)
                self._candidate = None
                return
        if peak_mass < s.switch_mass:
            self._candidate = None
            return
        if self._candidate is None or self._distance(self._candidate[1], peak_at) > s.gate_rad:
            self._candidate = (t_s, peak_at)
        self._candidate = (self._candidate[0], peak_at)
        # A voice that starts a turn (just after a gap) is taken at once; one that appears
        # mid-speech (an interruption, or reflections) must persist for reaction_time_s.
        turn_start = self._candidate[0] - self._speech_run_t_s <= s.onset_s
        if not turn_start and t_s - self._candidate[0] < s.reaction_time_s - 1e-9:
            return
        # Over a full circle a reflection can win bursts of windows (the mirror image behind a
        # wall): there the talker's majority over the last seconds counts too.
        if current is not None and s.majority_guard and self._votes.outvoted(
                peak_at, current, self._candidate[0], t_s, recent=self.circular):
            return
        if current is not None and self._distance(peak_at, current) <= s.reacquire_rad:
            self._start_talker(t_s, peak_at, elevation_rad)  # the same talker found again
            return
        if current is None or floor_open or t_s - self._last_switch_t_s >= s.min_hold_s:
            self._start_talker(t_s, peak_at, elevation_rad)
            self._walked = False
            if current is not None:
                self._last_switch_t_s = t_s
                self._switches.append((t_s, current, peak_at))
                self._update_wide(t_s)

    def _follow(self, t_s: float, azimuth_rad: float, elevation_rad: float | None) -> None:
        """Move the current talker towards the local posterior peak (at most ``max_rate_rad_s``
        since her last evidence); learn her rate and seat."""
        s = self.settings
        if self._talker_rad is not None and self._history:
            reach = s.max_rate_rad_s * (t_s - self._history[-1][0]) + self._step_rad
            azimuth_rad = self._on_grid(self._talker_rad + float(
                np.clip(self._offset(azimuth_rad, self._talker_rad), -reach, reach)))
        self._talker_rad = azimuth_rad
        self._history = [h for h in self._history if t_s - h[0] <= s.rate_window_s]
        self._history.append((t_s, azimuth_rad))
        self._talker_rate_rad_s = self._history_rate()
        if abs(self._talker_rate_rad_s) >= s.moving_rate_rad_s:
            # She walks: where she stood is no longer a seat.
            self._walked = True
            start = self._history[0][1]
            self._seats = [seat for seat in self._seats
                           if self._distance(seat.azimuth_rad, start) > s.gate_rad]
        elif not self._walked:
            self._remember(t_s, azimuth_rad)
        if elevation_rad is not None:
            self._elevation_rad = elevation_rad if self._elevation_rad is None else (
                self._elevation_rad + 0.2 * (elevation_rad - self._elevation_rad))

    def _history_rate(self) -> float:
        """Least-squares bearing rate of the talker's last ``rate_window_s`` (0 when too short)."""
        span_s = self._history[-1][0] - self._history[0][0] if self._history else 0.0
        if len(self._history) < 4 or span_s < 0.5 * self.settings.rate_window_s:
            return 0.0
        t, a = np.array(self._history).T
        if self.circular:
            a = np.unwrap(a)
        t = t - t.mean()
        return float(t @ (a - a.mean()) / (t @ t))

    def _remember(self, t_s: float, azimuth_rad: float) -> None:
        """A still talker's position joins the nearest seat within the gate (or starts one)."""
        near = [seat for seat in self._seats
                if self._distance(seat.azimuth_rad, azimuth_rad) <= self.settings.gate_rad]
        if near:
            seat = min(near, key=lambda x: self._distance(x.azimuth_rad, azimuth_rad))
            seat.add(t_s, azimuth_rad)
        else:
            self._seats.append(_Seat([azimuth_rad], t_s, self.circular))

    def _start_talker(self, t_s: float, azimuth_rad: float, elevation_rad: float | None) -> None:
        self._talker_rad, self._target_rad, self._talker_rate_rad_s = azimuth_rad, azimuth_rad, 0.0
        self._history, self._elevation_rad, self._candidate = [(t_s, azimuth_rad)], elevation_rad, None

    def _update_wide(self, t_s: float) -> None:
        """Go wide after repeated switching between the same two directions."""
        s = self.settings
        self._switches = [sw for sw in self._switches if t_s - sw[0] <= s.wide_window_s]
        if len(self._switches) < s.wide_after_switches:
            return
        mid = back_and_forth_midpoint(self._switches, s.gate_rad)
        if mid is not None:
            self._wide_rad = s.wide_azimuth_rad if s.wide_azimuth_rad is not None else (
                self._on_grid(mid))

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
            ahead = self._on_grid(talker + rate * s.lead_s)
            if self._distance(ahead, self._target_rad) > s.moving_deadband_rad:
                self._target_rad = ahead
        elif self._distance(talker, self._target_rad) > s.deadband_rad:
            self._target_rad = talker
        return TrackPoint(t_s, self._target_rad, self._elevation_rad, "talker", talker)


@lru_cache(maxsize=8)
def _shift_plan(cells: tuple[float, ...], n: int, circular: bool
                ) -> tuple[IntArray, IntArray, FloatArray, BoolArray, BoolArray]:
    """What :func:`_shift_rows` reads for a set of shifts (the same every step of a steady
    hop): the left and right cells (as indices into the flattened rows), the fraction between
    them, and where the edges hold."""
    x = np.arange(n, dtype=float)[None, :] - np.asarray(cells, dtype=float)[:, None]
    if circular:
        x = x % n
        j = np.minimum(np.floor(x).astype(np.int64), n - 1)
        right = (j + 1) % n
        none = np.zeros(x.shape, dtype=bool)
        plan = (j, right, x - j, none, none)
    else:
        j = np.clip(np.floor(x).astype(np.int64), 0, max(0, n - 2))
        plan = (j, np.minimum(j + 1, n - 1), x - j, x <= 0.0, x >= n - 1)
    row_start = n * np.arange(x.shape[0], dtype=np.int64)[:, None]
    plan = (plan[0] + row_start, plan[1] + row_start, *plan[2:])
    for part in plan:
        part.flags.writeable = False  # shared by every call with these shifts
    return plan


def _shift_rows(rows: FloatArray, cells: FloatArray, circular: bool = False) -> FloatArray:
    """Row ``k`` of ``rows`` (n_rows, n) moved by ``cells[k]`` cells (linear interpolation):
    ``np.interp(arange(n) - cells[k], arange(n), rows[k])`` for every row, with np.interp's
    formula; the edges hold, or the rows wrap round when ``circular``."""
    n = rows.shape[1]
    j, j_right, fraction, low, high = _shift_plan(tuple(np.asarray(cells, dtype=float).tolist()),
                                                  n, circular)
    flat = np.ascontiguousarray(rows).ravel()
    left, right = flat.take(j), flat.take(j_right)  # take_along_axis's values, cheaper
    out = (right - left) * fraction + left
    if circular:
        return np.asarray(out)
    out = np.where(low, rows[:, :1], out)
    return np.asarray(np.where(high, rows[:, n - 1 :], out))


def _wrap(angle_rad: float) -> float:
    """An angle in [-pi, pi)."""
    return float(np.remainder(angle_rad + np.pi, 2.0 * np.pi) - np.pi)
