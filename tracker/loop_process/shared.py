"""The shared memory between the control loop's process and the service: the engine's status and
loop timing, a ring of telemetry snapshots, and the talker tracker's latest target.

One :class:`SharedLoop` block (``multiprocessing.shared_memory``), created by the service and
attached by the loop's process. Each region has one writer and is read without locks:

- status and timing (written by the loop after every chunk) and the status text (faults, active
  talker, target source's name; written when it changes) each sit behind a *sequence counter*:
  the writer makes it odd, writes, makes it even; a reader copies and retries while the counter
  was odd or moved (a seqlock). Stores from Python land in program order on x86-64; a weaker
  memory model (ARM) would need fences this does not have.
- telemetry: a ring of ``RING_SLOTS`` snapshots and the count written so far; the writer fills a
  slot, then counts it; a reader keeps its own count and keeps a slot only if the writer had not
  come round to it again by the time it was copied.
- the target (written by the service, read by the loop): a seqlocked JSON text.

Numbers are float64; an absent value (no estimate, no tick yet) is NaN.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from multiprocessing import shared_memory
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.realtime import GAP_BUCKETS, LoopTiming
from tracker.targets import Target
from tracker.telemetry import EngineStatus, TelemetrySnapshot

MODES = ("tracking", "manual", "hold", "disabled", "fault")  # tracker.engine.MODES, by index
RING_SLOTS = 4096  # 4 s at 1 kHz ticks: the service reads every few ms
N_GAPS = len(GAP_BUCKETS) + 1

# float64 slots of the header
_STATUS_SEQ = 0
_STATUS = slice(1, 9)  # t, pan, tilt, pan target, tilt target, mode, tracking, driver enabled
_TIMING = slice(9, 21)  # period, ticks, last, max, mean, overruns, restarts, running, in thread,
#                         priority, last tick start (perf_counter), gap sum
_GAPS = slice(21, 21 + N_GAPS)
_TEXT_SEQ, _TEXT_LEN = 40, 41
_TARGET_SEQ, _TARGET_LEN = 42, 43
_RING_HEAD = 44
_HEADER = 48
_RING_FIELDS = 12  # t, pan, tilt, pan target, tilt target, pan u, tilt u, mode, tracking,
#                    source (0 none, 1 manual, 2 the named source), estimate azimuth, elevation
_TEXT_BYTES = 4096
_TARGET_BYTES = 1024
_FLOATS = _HEADER + RING_SLOTS * _RING_FIELDS
SIZE_BYTES = 8 * _FLOATS + _TEXT_BYTES + _TARGET_BYTES


@dataclass(frozen=True, slots=True)
class StatusText:
    """The status's strings: latched faults, the active talker, the target source's name."""

    faults: tuple[str, ...] = ()
    talker: str | None = None
    source: str | None = None


def _nan_if_none(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _none_if_nan(x: float) -> float | None:
    return None if math.isnan(x) else float(x)


class SharedLoop:
    """The shared block (see the module docstring): :meth:`create` in the service,
    :meth:`attach` in the loop's process; :meth:`close` on both sides, :meth:`unlink` by the creator."""

    def __init__(self, shm: shared_memory.SharedMemory, owner: bool) -> None:
        self._shm, self._owner = shm, owner
        buf = shm.buf
        assert buf is not None
        self._f: NDArray[np.float64] = np.ndarray((_FLOATS,), np.float64, buffer=buf)
        self._ring: NDArray[np.float64] = self._f[_HEADER:].reshape(RING_SLOTS, _RING_FIELDS)
        self._text = np.ndarray((_TEXT_BYTES,), np.uint8, buffer=buf, offset=8 * _FLOATS)
        self._target_buf = np.ndarray((_TARGET_BYTES,), np.uint8, buffer=buf,
                                      offset=8 * _FLOATS + _TEXT_BYTES)
        self._last_text: StatusText | None = None
        self._target_seq_seen = 0.0
        self._pushed: Target | None = None

    @classmethod
    def create(cls) -> SharedLoop:
        shm = shared_memory.SharedMemory(create=True, size=SIZE_BYTES)
        out = cls(shm, owner=True)
        out._f[:] = 0.0
        out._f[_STATUS] = math.nan
        out._f[_TIMING.start + 10] = math.nan  # no tick yet
        return out

    @classmethod
    def attach(cls, name: str) -> SharedLoop:
        return cls(shared_memory.SharedMemory(name=name), owner=False)

    @property
    def name(self) -> str:
        return str(self._shm.name)

    def close(self) -> None:
        """Let go of the block (the arrays over it are dropped first)."""
        del self._f, self._ring, self._text, self._target_buf
        self._shm.close()

    def unlink(self) -> None:
        if self._owner:
            self._shm.unlink()

    # -- the loop's side -----------------------------------------------------------------------
    def write_chunk(self, snap: TelemetrySnapshot, status: EngineStatus, enabled: bool,
                    timing: LoopTiming, last_start_s: float) -> None:
        """After a chunk: its snapshot into the ring, the status and timing, the text if changed."""
        f = self._f
        head = int(f[_RING_HEAD])
        row = self._ring[head % RING_SLOTS]
        source = 0.0 if snap.source is None else (1.0 if snap.source == "manual" else 2.0)
        row[:] = (snap.t_s, snap.pan_rad, snap.tilt_rad, snap.pan_target_rad, snap.tilt_target_rad,
                  snap.pan_u_v, snap.tilt_u_v, MODES.index(snap.mode), snap.tracking, source,
                  _nan_if_none(snap.estimate_azimuth_rad), _nan_if_none(snap.estimate_elevation_rad))
        f[_RING_HEAD] = head + 1
        named = snap.source if source == 2.0 else (self._last_text.source if self._last_text else None)
        self.write_status(status, enabled, timing, last_start_s, named)

    def write_status(self, status: EngineStatus, enabled: bool, timing: LoopTiming,
                     last_start_s: float, source: str | None = None) -> None:
        f = self._f
        f[_STATUS_SEQ] += 1.0
        f[_STATUS] = (status.t_s, status.pan_rad, status.tilt_rad, status.pan_target_rad,
                      status.tilt_target_rad, MODES.index(status.mode), status.tracking, enabled)
        f[_TIMING] = (timing.period_s, timing.ticks, timing.last_lateness_s, timing.max_lateness_s,
                      timing.mean_lateness_s, timing.overruns, timing.restarts, timing.running,
                      timing.in_thread, timing.priority, last_start_s, timing.gap_sum_s)
        if len(timing.gap_counts) == N_GAPS:
            f[_GAPS] = timing.gap_counts
        f[_STATUS_SEQ] += 1.0
        text = StatusText(tuple(status.faults), status.active_talker, source)
        if text != self._last_text:
            self._last_text = text
            _write_json(f, self._text, _TEXT_SEQ, _TEXT_LEN,
                        {"faults": list(text.faults), "talker": text.talker, "source": text.source})

    def read_target(self) -> Target | None:
        """The service's latest target (None: none yet, or the source said nothing)."""
        seq = self._f[_TARGET_SEQ]
        if seq != self._target_seq_seen:
            data = _read_json(self._f, self._target_buf, _TARGET_SEQ, _TARGET_LEN)
            if data is not None:
                self._target_seq_seen = seq
                self._pushed = None if data.get("pan_rad") is None else Target(**data)
        return self._pushed

    # -- the service's side --------------------------------------------------------------------
    def write_target(self, target: Target | None) -> None:
        data: dict[str, Any] = {} if target is None else asdict(target)
        _write_json(self._f, self._target_buf, _TARGET_SEQ, _TARGET_LEN, data)

    def ring_head(self) -> int:
        """Snapshots written so far."""
        return int(self._f[_RING_HEAD])

    def read_snapshots(self, since: int) -> tuple[list[TelemetrySnapshot], int]:
        """The snapshots written after the first ``since`` and the count to ask from next time
        (older ones the ring no longer holds are skipped)."""
        head = self.ring_head()
        start = max(since, head - RING_SLOTS + 1)
        if start >= head:
            return [], head
        idx = np.arange(start, head) % RING_SLOTS
        rows = self._ring[idx].copy()
        overwritten = self.ring_head() - RING_SLOTS + 1 - start  # slots the writer came round to
        if overwritten > 0:
            rows = rows[overwritten:]
        source = self.read_text().source
        return [_snapshot(r, source) for r in rows.tolist()], head

    def read_status(self) -> tuple[EngineStatus, bool] | None:
        """(the engine's status, whether the driver is enabled); None before the first write."""
        block = _read_seqlocked(self._f, _STATUS_SEQ, slice(_STATUS.start, _GAPS.stop))
        s = block[: _STATUS.stop - _STATUS.start]
        if math.isnan(s[0]):
            return None
        text = self.read_text()
        status = EngineStatus(float(s[0]), float(s[1]), float(s[2]), float(s[3]), float(s[4]),
                              MODES[int(s[5])], bool(s[6]), text.faults, text.talker)
        return status, bool(s[7])

    def read_timing(self, now_s: float) -> LoopTiming:
        """The loop's timing; ``now_s`` (perf_counter: CLOCK_MONOTONIC, shared between the
        processes) gives the last tick's age."""
        block = _read_seqlocked(self._f, _STATUS_SEQ, slice(_STATUS.start, _GAPS.stop))
        t = block[_TIMING.start - _STATUS.start: _TIMING.stop - _STATUS.start]
        gaps = block[_GAPS.start - _STATUS.start:]
        last_start = float(t[10])
        age = now_s - last_start if math.isfinite(last_start) else math.inf
        period = float(t[0])
        return LoopTiming(period, int(t[1]), float(t[2]), float(t[3]), float(t[4]), int(t[5]),
                          int(t[6]), bool(t[7]), bool(t[8]), int(t[9]), age,
                          tuple(b * period for b in GAP_BUCKETS), tuple(int(g) for g in gaps),
                          float(t[11]))

    def read_text(self) -> StatusText:
        data = _read_json(self._f, self._text, _TEXT_SEQ, _TEXT_LEN)
        if not data:
            return StatusText()
        return StatusText(tuple(data.get("faults") or ()), data.get("talker"), data.get("source"))


def _snapshot(r: list[float], source_name: str | None) -> TelemetrySnapshot:
    source = (None, "manual", source_name)[int(r[9])]
    return TelemetrySnapshot(r[0], r[1], r[2], r[3], r[4], r[5], r[6], MODES[int(r[7])], bool(r[8]),
                             source, _none_if_nan(r[10]), _none_if_nan(r[11]))


def _read_seqlocked(f: NDArray[np.float64], seq_at: int, part: slice,
                    tries: int = 1000) -> NDArray[np.float64]:
    """A consistent copy of ``f[part]`` (the last try's copy if the writer never paused)."""
    block = f[part].copy()
    for _ in range(tries):
        before = f[seq_at]
        if before % 2.0:
            continue
        block = f[part].copy()
        if f[seq_at] == before:
            break
    return block


def _write_json(f: NDArray[np.float64], region: NDArray[np.uint8], seq_at: int, len_at: int,
                data: dict[str, Any]) -> None:
    raw = json.dumps(data, separators=(",", ":")).encode()
    if len(raw) > region.size:  # a fault list longer than the region: cut, still valid JSON
        data = {**data, "faults": [f"{len(data.get('faults') or ())} faults (too long to show)"]}
        raw = json.dumps(data, separators=(",", ":")).encode()[: region.size]
    f[seq_at] += 1.0
    region[: len(raw)] = np.frombuffer(raw, np.uint8)
    f[len_at] = len(raw)
    f[seq_at] += 1.0


def _read_json(f: NDArray[np.float64], region: NDArray[np.uint8], seq_at: int, len_at: int,
               tries: int = 1000) -> dict[str, Any] | None:
    """The region's JSON (None if never written or the writer never paused)."""
    for _ in range(tries):
        before = f[seq_at]
        if before == 0.0:
            return None
        if before % 2.0:
            continue
        raw = region[: int(f[len_at])].tobytes()
        if f[seq_at] == before:
            try:
                out: dict[str, Any] = json.loads(raw)
            except ValueError:
                continue
            return out
    return None
