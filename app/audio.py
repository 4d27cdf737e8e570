"""The simulated room as the engine's target source: a meeting (talkers taking turns, one walking)
simulated once with the audio engineer's room model, run through the localizer and the talker
tracker (``tracker.audio``), and played back on the engine's clock, looping.

Each tracked point applies from the end of its analysis window (when a live system would have
it), exactly as ``tracker simulate meeting`` does. Building the meeting audio takes tens of
seconds, so it runs in a background thread at start-up and the result is cached in the data
folder; until it is ready the source says nothing and the engine holds.
"""

from __future__ import annotations

import logging
import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.targets import Target

log = logging.getLogger("app.audio")
FloatArray = NDArray[np.float64]
CACHE_VERSION = 1
ARRAYS_DIR = Path(__file__).resolve().parent.parent / "examples" / "arrays"


@dataclass(frozen=True, slots=True)
class TrackTable:
    """The tracked meeting: per analysis window, when it is available and what it says.

    Arrays have shape (n_windows,): ``end_s`` (s, increasing), ``target_az_rad`` (camera
    target; NaN = no shot yet), ``talker_az_rad`` (the talker the tracker follows; NaN = wide
    shot or none), ``estimate_az_rad`` / ``estimate_el_rad`` (the localizer's raw estimate; NaN
    outside speech). ``duration_s`` is the loop length.
    """

    end_s: FloatArray
    target_az_rad: FloatArray
    talker_az_rad: FloatArray
    estimate_az_rad: FloatArray
    estimate_el_rad: FloatArray
    duration_s: float

    def save(self, path: Path) -> None:
        tmp = path.with_name(path.name + ".part.npz")
        np.savez(
            tmp,
            version=CACHE_VERSION,
            end_s=self.end_s,
            target_az_rad=self.target_az_rad,
            talker_az_rad=self.talker_az_rad,
            estimate_az_rad=self.estimate_az_rad,
            estimate_el_rad=self.estimate_el_rad,
            duration_s=self.duration_s,
        )
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> TrackTable | None:
        try:
            d = np.load(path)
            if int(d["version"]) != CACHE_VERSION:
                return None
            return cls(
                d["end_s"],
                d["target_az_rad"],
                d["talker_az_rad"],
                d["estimate_az_rad"],
                d["estimate_el_rad"],
                float(d["duration_s"]),
            )
        except (OSError, KeyError, ValueError):
            return None


def _nan(x: float | None) -> float:
    return math.nan if x is None else float(x)


def track_meeting(seed: int = 1, duration_s: float = 60.0) -> TrackTable:
    """Simulate the meeting and run localizer + tracker over it (seconds to a minute of CPU)."""
    from tracker.audio.array import load_array
    from tracker.audio.pipeline import Pipeline
    from tracker.scenarios.meeting import MeetingSettings, build_meeting

    settings = MeetingSettings()
    array = load_array(ARRAYS_DIR / settings.array_file)
    recording, _ = build_meeting(seed, duration_s, settings, array)
    pipeline = Pipeline(
        array,
        recording.fs_hz,
        settings.method,
        settings.windows,
        tracking=settings.tracking,
        localizer_options={"azimuth_range_rad": (-np.pi / 2, np.pi / 2)},
    )
    frames = pipeline.estimate_frames(recording.audio)
    track = pipeline.track(frames)
    return TrackTable(
        end_s=np.array([f.end_s for f in frames]),
        target_az_rad=np.array([p.azimuth_rad if p.shot != "none" else math.nan for p in track]),
        talker_az_rad=np.array(
            [_nan(p.talker_azimuth_rad) if p.shot == "talker" else math.nan for p in track]
        ),
        estimate_az_rad=np.array([f.azimuth_rad if f.speech else math.nan for f in frames]),
        estimate_el_rad=np.array([_nan(f.elevation_rad) if f.speech else math.nan for f in frames]),
        duration_s=float(duration_s),
    )


class MeetingSource:
    """A target source (``name``, ``target_at``) replaying a tracked meeting on engine time."""

    def __init__(self, table: TrackTable | None = None, name: str = "simulated meeting") -> None:
        self.name = name
        self.table = table
        self.note = "ready" if table is not None else "preparing the simulated meeting"
        self.worker: Any = None  # the subprocess building the meeting, while it runs
        self.closed = False

    def close(self) -> None:
        """Stop building the meeting (at shutdown)."""
        self.closed = True
        proc = self.worker
        if proc is not None and proc.poll() is None:
            proc.terminate()

    def target_at(self, t_s: float) -> Target | None:
        """The tracker's target at engine time ``t_s`` (looping), or None before the first shot."""
        tab = self.table
        if tab is None:
            return None
        t = t_s % tab.duration_s
        i = int(np.searchsorted(tab.end_s, t, side="right")) - 1
        if i < 0 or not math.isfinite(tab.target_az_rad[i]):
            return None
        talker = tab.talker_az_rad[i]
        label = f"talker at {math.degrees(talker):+.0f}°" if math.isfinite(talker) else "wide shot"
        est_az, est_el = tab.estimate_az_rad[i], tab.estimate_el_rad[i]
        return Target(
            pan_rad=float(tab.target_az_rad[i]),
            tilt_rad=0.0,  # the planar array cannot resolve elevation; the camera keeps eye level
            talker=label,
            azimuth_rad=float(est_az) if math.isfinite(est_az) else None,
            elevation_rad=float(est_el) if math.isfinite(est_el) else None,
        )


def settings_digest() -> str:
    """A short digest of the meeting and tracker settings: a cache made with others is not reused."""
    import hashlib

    from tracker.scenarios.meeting import MeetingSettings

    return hashlib.sha256(f"{CACHE_VERSION}:{MeetingSettings()!r}".encode()).hexdigest()[:10]


def start_meeting_source(
    engine: Any, cache_dir: Path, seed: int = 1, duration_s: float = 60.0
) -> MeetingSource:
    """Plug a MeetingSource into ``engine`` now; fill it from the cache or a background thread."""
    source = MeetingSource()
    engine.set_target_source(source)
    cache = cache_dir / f"meeting_seed{seed}_{int(duration_s)}s_{settings_digest()}.npz"
    table = TrackTable.load(cache) if cache.exists() else None
    if table is not None:
        source.table, source.note = table, "ready"
        return source

    def work() -> None:
        # In a separate process: the room simulation would otherwise hold the GIL for long
        # stretches and make the engine loop (same process) miss its real-time pace.
        import subprocess
        import sys

        try:
            cmd = [sys.executable, "-m", "app.audio", str(seed), str(duration_s), str(cache)]
            proc = subprocess.Popen(
                cmd,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
                cwd=Path(__file__).resolve().parent.parent,
            )
            source.worker = proc
            _, err = proc.communicate(timeout=900)
            source.worker = None
            if proc.returncode != 0:
                tail = err.strip().splitlines()
                raise RuntimeError(tail[-1] if tail else f"worker exited with {proc.returncode}")
            tab = TrackTable.load(cache)
            if tab is None:
                raise RuntimeError(f"the tracked meeting was not written to {cache}")
            source.table, source.note = tab, "ready"
            log.info("simulated meeting ready: %d analysis windows", tab.end_s.size)
        except Exception as exc:  # the console must keep working with manual pointing
            if source.closed:
                return
            source.note = f"simulated meeting failed: {type(exc).__name__}: {exc}"
            log.exception("building the simulated meeting failed")

    threading.Thread(target=work, name="simulated-meeting", daemon=True).start()
    return source


if __name__ == "__main__":  # the worker process: python -m app.audio SEED DURATION_S OUT.npz
    import sys

    track_meeting(int(sys.argv[1]), float(sys.argv[2])).save(Path(sys.argv[3]))
