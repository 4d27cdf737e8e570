"""Talker tracking and the camera-operator policy: Kalman smoothing, gating, switching, wide shot.

Frames (direction estimates flagged as speech or not) go in one at a time, in time order; each
returns the direction the camera should point at. The policy imitates a good operator:

* only the more confident speech frames count (confidence above the running
  ``confidence_quantile``, 30 %, of the last ``confidence_window_s``): in a reverberant room
  the low-confidence windows are the ones dominated by reflections;
* a direction must persist for ``reaction_time_s`` (at least three frames) before the camera
  goes there, and when a long window is supplied it must point there too (a single wrong
  estimate, a cough or a burst of reflections does not move the camera);
* the current talker's Kalman filter (constant velocity) takes the long window's estimate
  (precise, but lagging a walker, so trusted less the faster the talker moves) and the short
  window's (quick, noisy) when they fall inside the gate; estimates outside it are evidence
  for up to three candidate talkers;
* a candidate is confirmed early (adaptive confirmation) when ``fast_confirm_hits`` confident
  short windows agree on it and the long window already points there;
* confident frames the speech detector rejected within ``onset_lookback_s`` before a new
  candidate, pointing the same way, count for it (the detector accepts a turn a few frames
  late; the localizer already had the direction);
* a confirmed candidate within ``reacquire_rad`` of the current talker's track is that
  talker found again (a walker the track lost) when the track had no evidence for
  ``reacquire_after_s``: the track restarts there, but it is not a switch (no hold, no count
  towards the wide shot); next to a track that has evidence it is reflections and ignored;
* within a turn, confident frames the speech detector rejected still update the current
  talker inside the nominal gate (a walker's quiet syllables), and a moving talker's position
  coasts at her rate for up to ``coast_s`` without evidence;
* after a switch the camera stays at least ``min_hold_s`` unless the floor was silent for
  longer than ``pause_tolerance_s`` (then the next talker is taken as soon as confirmed);
* pauses shorter than ``pause_tolerance_s`` keep a talker's claim to the floor;
* within a talker the shot moves only when the smoothed direction leaves the ``deadband_rad``
  around the current shot; a talker whose bearing rate exceeds ``moving_rate_rad_s`` (a
  walker) is followed in ``moving_deadband_rad`` steps, led by ``rate * lead_s`` (``lead_s``:
  the latency from a short window's centre to the camera arriving, 0.15 s half window +
  0.05 s half hop + about 0.1 s of camera, so the shot lands where she is, not where she was);
* after ``wide_after_switches`` switches back and forth between the same two directions within
  ``wide_window_s``, the camera takes a wide shot between them until one talker has held the
  floor for ``wide_release_s``;
* the majority rules (``majority_guard``, :class:`WindowVotes`): a candidate is not taken
  while, since it first appeared, fewer confident short windows pointed at it than at the
  current talker, who kept talking (a reflection, such as the mirror image behind an array on
  a wall, wins a minority of windows while its source talks on; a new talker wins the windows
  after the old one stops); and a direction that won a steady majority of the last
  ``majority_window_s`` (at least ``majority_min_windows`` windows, ``majority_ratio`` times
  the current talker's) is taken even when the long window disagrees, once the hold is over,
  or at once when the current track has not had three windows of its own since it started (a
  track that went to a reflection comes back);
* with a field of view (``view``), estimates outside it count for nothing and the shot never
  leaves it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tracker.audio.array import FieldOfView
from tracker.errors import ConfigError

_MAX_CANDIDATES = 3
STEADY_WINDOWS = 3  # a talker with fewer windows since a candidate appeared is not steady
_GAP_S = 0.25  # a pause this long before a new direction ends the current talker's turn
_VIEW_MARGIN_RAD = float(np.deg2rad(2.0))  # a grid search refines up to 2° past its edge


def _wrap(angle_rad: float) -> float:
    """Wrap into (-pi, pi]."""
    return float(-((-angle_rad + np.pi) % (2 * np.pi) - np.pi))


@dataclass(slots=True)
class WindowVotes:
    """Where recent confident speech windows pointed, for the trackers' majority rules.

    Parameters
    ----------
    gate_rad : a window within this of a direction votes for it.
    window_s, min_windows, ratio : a direction is a steady majority when, over the last
        ``window_s``, at least ``min_windows`` windows and ``ratio`` times as many as the
        current talker's voted for it.
    """

    gate_rad: float
    window_s: float = 3.0
    min_windows: int = 6
    ratio: float = 2.0
    _entries: list[tuple[float, float]] = field(default_factory=list)  # (t_s, azimuth_rad)

    def add(self, t_s: float, azimuth_rad: float) -> None:
        """A confident speech window's direction (time order)."""
        keep_s = max(10.0, self.window_s)
        entries = self._entries
        old = 0  # the entries are in time order: the ones to drop are the first ones
        while old < len(entries) and t_s - entries[old][0] > keep_s:
            old += 1
        if old:
            del entries[:old]
        entries.append((t_s, _wrap(azimuth_rad)))

    def near(self, azimuth_rad: float, since_s: float) -> int:
        """Windows since ``since_s`` within the gate of ``azimuth_rad``."""
        return sum(t >= since_s - 1e-9 and abs(_wrap(a - azimuth_rad)) <= self.gate_rad
                   for t, a in self._entries)

    def outvoted(self, candidate_rad: float, current_rad: float, since_s: float, t_s: float,
                 recent: bool = True) -> bool:
        """True when fewer windows voted for the candidate than for the current talker, who
        holds a steady majority: since ``since_s`` (the candidate's first appearance), or, with
        ``recent``, over the last ``window_s`` when she was talking when the candidate appeared
        (a window of hers since, or less than ``_GAP_S`` before: a new talker who takes over
        after a pause is not held back, one who interrupts waits for the majority)."""
        for_current = self.near(current_rad, since_s)
        if for_current >= STEADY_WINDOWS and self.near(candidate_rad, since_s) < for_current:
            return True
        if not recent:
            return False
        last = max((t for t, a in self._entries
                    if t < since_s and abs(_wrap(a - current_rad)) <= self.gate_rad),
                   default=-np.inf)
        if for_current == 0 and since_s - last > _GAP_S:
            return False
        since = t_s - self.window_s
        for_current = self.near(current_rad, since)
        return for_current >= STEADY_WINDOWS and self.near(candidate_rad, since) < for_current

    def majority(self, t_s: float, current_rad: float) -> float | None:
        """The direction of a steady majority away from the current talker (more than two
        gates), or None; its azimuth is the mean of its windows.

        Steady: over the last ``window_s`` at least ``min_windows`` windows voted for it and
        ``ratio`` times as many as for the current talker, and it still leads over the last
        third of that time (a talker who just stopped is no majority: her successor is not
        undone).
        """
        recent = [(t, a) for t, a in self._entries if t_s - t <= self.window_s + 1e-9]
        if len(recent) < self.min_windows:
            return None
        angles = [a for _, a in recent]
        votes = [[b for b in angles if abs(_wrap(b - a)) <= self.gate_rad] for a in angles]
        best = max(range(len(angles)), key=lambda i: (len(votes[i]), i))
        members = votes[best]
        centre = float(np.angle(np.mean(np.exp(1j * np.asarray(members)))))

        def count(direction: float, since_s: float) -> int:
            return sum(t >= since_s - 1e-9 and abs(_wrap(a - direction)) <= self.gate_rad
                       for t, a in recent)

        if (len(members) < self.min_windows or abs(_wrap(centre - current_rad)) <= 2.0 * self.gate_rad
                or len(members) < self.ratio * count(current_rad, t_s - self.window_s)):
            return None
        lately = t_s - self.window_s / 3.0
        if count(centre, lately) < max(STEADY_WINDOWS, self.ratio * count(current_rad, lately)):
            return None
        return centre


def back_and_forth_midpoint(switches: list[tuple[float, float, float]], near_rad: float
                            ) -> float | None:
    """The wide shot's direction, or None: the midpoint of the last switch's two ends when
    every switch in ``switches`` (time, from, to; rad) went between those two directions
    (each end within ``near_rad`` of one of them)."""
    a, b = switches[-1][1], switches[-1][2]
    ends = [x for sw in switches for x in sw[1:]]
    if all(min(abs(_wrap(x - a)), abs(_wrap(x - b))) <= near_rad for x in ends):
        return float(np.angle(np.exp(1j * a) + np.exp(1j * b)))
    return None


@dataclass(frozen=True, slots=True)
class TrackerSettings:
    """Talker tracker and switching policy; every field adjustable, defaults for a meeting room."""

    min_confidence: float = 0.05
    confidence_quantile: float = 0.3
    confidence_window_s: float = 10.0
    measurement_std_rad: float = float(np.deg2rad(3.0))
    fine_std_rad: float = float(np.deg2rad(2.0))
    accel_std_rad_s2: float = float(np.deg2rad(10.0))
    max_rate_rad_s: float = float(np.deg2rad(30.0))
    short_updates_with_fine: bool = True
    gate_rad: float = float(np.deg2rad(8.0))
    reaction_time_s: float = 0.2
    candidate_share: float = 0.6
    min_hold_s: float = 2.0
    pause_tolerance_s: float = 1.5
    deadband_rad: float = float(np.deg2rad(3.0))
    wide_after_switches: int = 4
    wide_window_s: float = 20.0
    wide_release_s: float = 6.0
    wide_azimuth_rad: float | None = None
    lead_s: float = 0.3
    moving_rate_rad_s: float = float(np.deg2rad(5.0))
    moving_deadband_rad: float = float(np.deg2rad(1.0))
    onset_lookback_s: float = 0.5
    fast_confirm_hits: int = 2
    unvoiced_updates: bool = True
    unvoiced_std_factor: float = 1.5
    coast_s: float = 0.5
    reacquire_rad: float = float(np.deg2rad(20.0))
    reacquire_after_s: float = 0.2
    majority_guard: bool = True
    majority_window_s: float = 3.0
    majority_min_windows: int = 6
    majority_ratio: float = 2.0

    def __post_init__(self) -> None:
        for name in ("reaction_time_s", "min_hold_s", "pause_tolerance_s", "wide_window_s",
                     "wide_release_s", "gate_rad", "measurement_std_rad", "fine_std_rad",
                     "accel_std_rad_s2", "lead_s", "moving_rate_rad_s", "moving_deadband_rad",
                     "onset_lookback_s", "coast_s", "reacquire_rad",
                     "reacquire_after_s"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise ConfigError(f"tracker setting {name}={value} must be a finite value >= 0")
        if self.deadband_rad < 0 or self.deadband_rad > np.deg2rad(30):
            raise ConfigError(f"deadband_rad={self.deadband_rad} outside 0-30°")
        if not 0.0 <= self.confidence_quantile < 1.0:
            raise ConfigError(f"confidence_quantile={self.confidence_quantile} must be in [0, 1)")
        if not 0.0 < self.candidate_share <= 1.0:
            raise ConfigError(f"candidate_share={self.candidate_share} must be in (0, 1]")
        if self.wide_after_switches < 2:
            raise ConfigError(f"wide_after_switches={self.wide_after_switches} must be >= 2")


@dataclass(frozen=True, slots=True)
class TrackPoint:
    """The camera target after one frame.

    Attributes
    ----------
    t_s : frame time.
    azimuth_rad, elevation_rad : where the camera should point (elevation None if unknown).
    shot : "none" (no talker yet), "talker" or "wide".
    talker_azimuth_rad : the smoothed direction of the current talker (None before the first).
    """

    t_s: float
    azimuth_rad: float
    elevation_rad: float | None
    shot: str
    talker_azimuth_rad: float | None


@dataclass(slots=True)
class _Kalman:
    """Constant-velocity Kalman filter on an angle (state: angle, rate)."""

    x: np.ndarray
    p: np.ndarray
    t_s: float

    def predict(self, t_s: float, accel_std: float) -> None:
        dt = max(0.0, t_s - self.t_s)
        f = np.array([[1.0, dt], [0.0, 1.0]])
        q = accel_std**2 * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
        self.x = f @ self.x
        self.x[0] = _wrap(self.x[0])
        self.p = f @ self.p @ f.T + q
        self.t_s = t_s

    def innovation(self, z: float) -> float:
        return _wrap(z - self.x[0])

    def update(self, z: float, r: float, lag_s: float = 0.0) -> None:
        """Measurement of the angle ``lag_s`` ago: ``z = x - lag_s * rate + noise``."""
        h = np.array([1.0, -lag_s])
        y = _wrap(z - float(h @ self.x))
        s = float(h @ self.p @ h) + r
        k = self.p @ h / s
        self.x = self.x + k * y
        self.x[0] = _wrap(self.x[0])
        self.p = self.p - np.outer(k, h @ self.p)

    def limit_rate(self, max_rate: float) -> None:
        """People walk; a talker's bearing rate beyond ``max_rate`` is filter noise."""
        self.x[1] = float(np.clip(self.x[1], -max_rate, max_rate))


@dataclass(slots=True)
class _Candidate:
    """Evidence for a new direction; its position follows its latest hits (a walker moves)."""

    first_t_s: float
    last_t_s: float
    azimuth_rad: float
    first_frame: int
    hits: int = 1

    def add(self, t_s: float, z: float) -> None:
        self.azimuth_rad = _wrap(self.azimuth_rad + 0.5 * _wrap(z - self.azimuth_rad))
        self.last_t_s = t_s
        self.hits += 1


@dataclass(slots=True)
class TalkerTracker:
    """Feed frames with :meth:`step`; see the module docstring for the policy.

    ``view`` (optional): the field of view talkers can be in (base frame); estimates more than
    2° outside it are ignored and the shot is kept inside it.
    """

    settings: TrackerSettings = field(default_factory=TrackerSettings)
    view: FieldOfView | None = None
    _talker: _Kalman | None = None
    _elevation_rad: float | None = None
    _candidates: list[_Candidate] = field(default_factory=list)
    _frames: int = 0
    _last_switch_t_s: float = -np.inf
    _last_speech_t_s: float = -np.inf
    _target_rad: float = 0.0
    _switches: list[tuple[float, float, float]] = field(default_factory=list)
    _wide_rad: float | None = None
    _confidences: list[tuple[float, float]] = field(default_factory=list)
    _unvoiced: list[tuple[float, float, float]] = field(default_factory=list)
    _votes: WindowVotes = field(init=False)
    _talker_since_s: float = -np.inf  # when the current track started

    def __post_init__(self) -> None:
        s = self.settings
        self._votes = WindowVotes(s.gate_rad, s.majority_window_s, s.majority_min_windows,
                                  s.majority_ratio)

    def step(self, t_s: float, azimuth_rad: float, elevation_rad: float | None,
             confidence: float, speech: bool, fine_azimuth_rad: float | None = None,
             fine_lag_s: float = 0.0) -> TrackPoint:
        """Take one frame (time order) and return the camera target after it.

        ``azimuth_rad`` comes from a short window (quick to show a new talker);
        ``fine_azimuth_rad``, when given, from a longer window ending at the same time: it
        refines the current talker's position but never starts a switch; its centre lies
        ``fine_lag_s`` before the short window's, so it counts less while the talker walks.
        """
        s = self.settings
        finite = bool(np.isfinite(azimuth_rad)) and self._in_view(azimuth_rad)
        confident = speech and finite and confidence >= s.min_confidence
        if confident and s.confidence_quantile > 0.0:
            confident = self._confident(t_s, confidence)
        if not speech and finite and confidence >= s.min_confidence:
            # Kept for the onset look-back: the speech detector needs a few frames to accept
            # the start of a turn, the localizer does not.
            horizon = t_s - s.onset_lookback_s
            self._unvoiced = [u for u in self._unvoiced if u[0] >= horizon]
            self._unvoiced.append((t_s, _wrap(azimuth_rad), confidence))
            if s.unvoiced_updates:
                self._follow_unvoiced(t_s, _wrap(azimuth_rad), confidence)
        fine = None
        if (speech and fine_azimuth_rad is not None and np.isfinite(fine_azimuth_rad)
                and self._in_view(fine_azimuth_rad)):
            fine = _wrap(fine_azimuth_rad)
        if confident or fine is not None:
            floor_was_open = t_s - self._last_speech_t_s > s.pause_tolerance_s
            if confident:
                self._frames += 1
                self._votes.add(t_s, azimuth_rad)
            short = _wrap(azimuth_rad) if confident else None
            self._observe(t_s, short, elevation_rad, floor_was_open, fine, fine_lag_s)
            self._last_speech_t_s = t_s
        return self._target(t_s)

    def _in_view(self, azimuth_rad: float) -> bool:
        view = self.view
        return view is None or view.full_circle or bool(
            view.contains_azimuth(azimuth_rad, _VIEW_MARGIN_RAD))

    def _outvoted(self, candidate: _Candidate, t_s: float) -> bool:
        """The majority guard (module docstring): since ``candidate`` first appeared, fewer
        confident short windows pointed at it than at the current talker, who kept talking."""
        if not self.settings.majority_guard or self._talker is None:
            return False
        # Over a full circle a reflection can win bursts of windows (the mirror image behind a
        # wall): there the talker's majority over the last seconds counts too.
        full_circle = self.view is not None and self.view.full_circle
        return self._votes.outvoted(candidate.azimuth_rad, float(self._talker.x[0]),
                                    candidate.first_t_s, t_s, recent=full_circle)

    def _follow_unvoiced(self, t_s: float, z: float, confidence: float) -> None:
        """Within a turn, a confident frame the speech detector rejected, inside the nominal
        gate, still updates the current talker (quiet syllables of a walker who keeps walking).

        It never starts a candidate and does not hold the floor.
        """
        s = self.settings
        talker = self._talker
        if (talker is None or t_s - self._last_speech_t_s > s.pause_tolerance_s
                or confidence < max(self._confidence_level(), s.min_confidence)):
            return
        before = (talker.x.copy(), talker.p.copy(), talker.t_s)
        talker.predict(t_s, s.accel_std_rad_s2)
        if abs(talker.innovation(z)) <= s.gate_rad:
            talker.update(z, (s.unvoiced_std_factor * s.measurement_std_rad) ** 2)
            talker.limit_rate(s.max_rate_rad_s)
        else:
            talker.x, talker.p, talker.t_s = before

    def _confident(self, t_s: float, confidence: float) -> bool:
        """Keep frames above the running quantile of recent speech-frame confidences."""
        horizon = t_s - self.settings.confidence_window_s
        self._confidences = [(t, c) for t, c in self._confidences if t >= horizon]
        self._confidences.append((t_s, confidence))
        return bool(confidence >= self._confidence_level())

    def _confidence_level(self) -> float:
        """The running confidence quantile (0 until five speech frames were seen)."""
        if len(self._confidences) < 5 or self.settings.confidence_quantile <= 0.0:
            return 0.0
        return float(np.quantile([c for _, c in self._confidences],
                                 self.settings.confidence_quantile))

    # -- talker evidence -------------------------------------------------------------------

    def _observe(self, t_s: float, z: float | None, elevation_rad: float | None,
                 floor_open: bool, fine: float | None = None, fine_lag_s: float = 0.0) -> None:
        """Update the talker with ``fine`` and/or ``z``; ``z`` outside the gate is candidate evidence.

        ``z`` is None when the short window was not confident enough to count.
        """
        s = self.settings
        # The steady majority is taken once the hold is over, or at once when the current track
        # never had a steady vote of its own (a track that went to a reflection).
        if (self._talker is not None and z is not None and s.majority_guard
                and (t_s - self._last_switch_t_s >= s.min_hold_s or self._votes.near(
                    float(self._talker.x[0]), self._talker_since_s) < STEADY_WINDOWS)):
            majority = self._votes.majority(t_s, float(self._talker.x[0]))
            if majority is not None:  # the track is off the steady majority: go there
                self._switch(t_s, majority, elevation_rad)
                return
        if self._talker is not None:
            if floor_open:
                self._talker.x[1] = 0.0  # a talker who paused is not still walking
            before = (self._talker.x.copy(), self._talker.p.copy(), self._talker.t_s)
            self._talker.predict(t_s, s.accel_std_rad_s2)
            # The gate widens with the track's uncertainty, but never enough to swallow a
            # neighbour: at most 1.5 times the nominal gate.
            spread = 3.0 * np.sqrt(self._talker.p[0, 0] + s.measurement_std_rad**2)
            gate = float(np.clip(spread, s.gate_rad, 1.5 * s.gate_rad))
            short_in_gate = z is not None and abs(self._talker.innovation(z)) <= gate
            fine_in_gate = fine is not None and abs(self._talker.innovation(fine)) <= gate
            if fine_in_gate:
                assert fine is not None
                # The long window lags a walker by fine_lag_s: trust it less the faster the
                # talker moves, so the short windows carry a walker and the long one a sitter.
                lag_error = fine_lag_s * float(self._talker.x[1])
                self._talker.update(fine, s.fine_std_rad**2 + lag_error**2)
            if short_in_gate and (s.short_updates_with_fine or not fine_in_gate):
                assert z is not None
                self._talker.update(z, s.measurement_std_rad**2)
            if fine_in_gate or short_in_gate:
                self._talker.limit_rate(s.max_rate_rad_s)
            else:
                # No evidence for this talker: the track stays where it was (no coasting).
                self._talker.x, self._talker.p, self._talker.t_s = before
            if short_in_gate:
                self._update_elevation(elevation_rad)
            fine_elsewhere = fine is not None and abs(self._talker.innovation(fine)) > gate
            if short_in_gate or (z is None and not fine_elsewhere):
                self._expire_candidates(t_s)
                return
        short_confident = z is not None
        if z is None:
            # A long window pointing away from the talker (or at the first talker) is
            # evidence for a candidate too, when the short one was not confident.
            if fine is None:
                return
            z = fine
        c = self._add_candidate_evidence(t_s, z)
        persistent = t_s - c.first_t_s >= s.reaction_time_s - 1e-9 and c.hits >= 3
        if fine is None:
            confirmed = persistent and c.hits >= s.candidate_share * (
                self._frames - c.first_frame + 1)
        else:
            # With a long window as well, it must agree: a burst of reflections in the short
            # windows never moves the long one, a new talker does within half its length.
            # A new talker the short windows agree on twice and the long window already
            # points at is confirmed before the reaction time (adaptive confirmation).
            fast = c.hits >= s.fast_confirm_hits and short_confident
            confirmed = (persistent or fast) and abs(_wrap(fine - c.azimuth_rad)) <= s.gate_rad
        if confirmed and self._outvoted(c, t_s):
            return
        if confirmed and self._talker is not None and (
                abs(self._talker.innovation(c.azimuth_rad)) <= s.reacquire_rad):
            # Near the current talker: her again if her track has had no evidence for
            # reacquire_after_s (lost), else reflections next to a healthy track.
            if t_s - self._talker.t_s < s.reacquire_after_s:
                return
            self._switch(t_s, c.azimuth_rad, elevation_rad)
            return
        may_switch = floor_open or t_s - self._last_switch_t_s >= s.min_hold_s
        if confirmed and (may_switch or self._talker is None):
            self._switch(t_s, c.azimuth_rad, elevation_rad)

    def _add_candidate_evidence(self, t_s: float, z: float) -> _Candidate:
        """Add ``z`` to the nearest candidate within the gate, or start a new one."""
        self._expire_candidates(t_s)
        near = [c for c in self._candidates if abs(_wrap(z - c.azimuth_rad)) <= self.settings.gate_rad]
        if near:
            best = min(near, key=lambda c: abs(_wrap(z - c.azimuth_rad)))
            best.add(t_s, z)
            return best
        fresh = _Candidate(t_s, t_s, z, self._frames)
        # Onset look-back: confident unvoiced frames just before that point the same way are
        # the start of this turn (the speech detector accepts a turn a few frames late).
        level = self._confidence_level()
        earlier = [u for u in self._unvoiced
                   if 0.0 < t_s - u[0] <= self.settings.onset_lookback_s and u[2] >= level
                   and abs(_wrap(u[1] - z)) <= self.settings.gate_rad]
        if earlier:
            fresh.first_t_s = min(u[0] for u in earlier)
            fresh.hits += len(earlier)
            fresh.first_frame -= len(earlier)
        self._candidates = [*self._candidates[-(_MAX_CANDIDATES - 1):], fresh]
        return fresh

    def _expire_candidates(self, t_s: float) -> None:
        timeout = min(self.settings.pause_tolerance_s, max(0.6, 2 * self.settings.reaction_time_s))
        self._candidates = [c for c in self._candidates if t_s - c.last_t_s <= timeout]

    def _switch(self, t_s: float, azimuth_rad: float, elevation_rad: float | None) -> None:
        s = self.settings
        previous = float(self._talker.x[0]) if self._talker is not None else None
        p0 = np.diag([s.measurement_std_rad**2, np.deg2rad(10.0) ** 2])
        if previous is not None and abs(_wrap(azimuth_rad - previous)) <= s.reacquire_rad:
            # The same talker found again a little away from her track (a walker the track
            # lost): a new track (at rest: a kept rate can run away), but not a switch (no
            # hold, no wide count).
            previous = None
        else:
            self._last_switch_t_s = t_s
        self._talker = _Kalman(np.array([azimuth_rad, 0.0]), p0, t_s)
        self._talker_since_s = t_s
        self._elevation_rad = elevation_rad
        self._candidates = []
        self._target_rad = azimuth_rad
        if previous is not None:
            self._switches.append((t_s, previous, azimuth_rad))
            self._update_wide(t_s)

    def _update_elevation(self, elevation_rad: float | None) -> None:
        if elevation_rad is None:
            return
        if self._elevation_rad is None:
            self._elevation_rad = elevation_rad
        else:
            self._elevation_rad += 0.2 * (elevation_rad - self._elevation_rad)

    # -- shot policy -----------------------------------------------------------------------

    def _update_wide(self, t_s: float) -> None:
        """Go wide after repeated switching between the same two directions."""
        s = self.settings
        recent = [sw for sw in self._switches if t_s - sw[0] <= s.wide_window_s]
        self._switches = recent
        if len(recent) < s.wide_after_switches:
            return
        mid = back_and_forth_midpoint(recent, s.gate_rad)
        if mid is not None:
            self._wide_rad = s.wide_azimuth_rad if s.wide_azimuth_rad is not None else mid

    def _target(self, t_s: float) -> TrackPoint:
        point = self._shot(t_s)
        if self.view is None or self.view.full_circle or point.shot == "none":
            return point
        # The shot stays in view (a walker's lead, or a wide shot's midpoint, may leave it).
        return TrackPoint(point.t_s, self.view.nearest_azimuth(point.azimuth_rad),
                          point.elevation_rad, point.shot, point.talker_azimuth_rad)

    def _shot(self, t_s: float) -> TrackPoint:
        s = self.settings
        if self._talker is None:
            return TrackPoint(t_s, self._target_rad, self._elevation_rad, "none", None)
        talker = float(self._talker.x[0])
        if self._wide_rad is not None:
            if t_s - self._last_switch_t_s < s.wide_release_s:
                return TrackPoint(t_s, self._wide_rad, None, "wide", talker)
            self._wide_rad = None
            self._switches.clear()
            self._target_rad = talker
        rate = float(self._talker.x[1])
        if abs(rate) >= s.moving_rate_rad_s:
            # A walker: where she is now (coasting at most coast_s since the last evidence),
            # led by the latency, followed closely (the shaping smooths the steps).
            coast = min(max(0.0, t_s - self._talker.t_s), s.coast_s)
            ahead = _wrap(talker + rate * (coast + s.lead_s))
            if abs(_wrap(ahead - self._target_rad)) > s.moving_deadband_rad:
                self._target_rad = ahead
        elif abs(_wrap(talker - self._target_rad)) > s.deadband_rad:
            self._target_rad = talker
        return TrackPoint(t_s, self._target_rad, self._elevation_rad, "talker", talker)
