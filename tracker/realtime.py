"""The control loop's own clock and thread: deadlines on ``time.perf_counter``, lateness kept.

A :class:`PacedLoop` calls ``step()`` in its own thread at ``period_s``: ticks are due at whole
multiples of the period on ``time.perf_counter``; the thread sleeps until ``spin_s`` before
that and busy-waits the rest (``time.sleep`` overshoots by 50-100 µs on Linux). The loop
catches up a late tick by running the next ones at once; more than ``max_behind_s`` behind it
drops the missed ticks and starts afresh (an engine on the twin then runs behind the wall
clock by that much).

Timing (:class:`LoopTiming`): a tick's *lateness* is how long after its due time it started;
an *overrun* is a tick that started after the next one was due (late by a whole period or
more); a tick's *gap* is the time since the previous tick started (one period when on time),
counted in buckets of ``GAP_BUCKETS`` periods (a histogram the service exports), and
``last_tick_age_s`` how long ago the latest tick started (a loop stuck in a tick shows it
growing). While the loop runs, the interpreter's switch interval is lowered to ``switch_interval_s``
(default 0.5 ms, Python's is 5 ms): a thread waiting for the GIL asks its holder to let go
after that long, so a busy web thread delays a tick by about that much, not 5 ms.

``priority`` (1-99, Linux) puts the loop's thread in the SCHED_FIFO real-time class, so the
kernel runs it as soon as it wakes even on a loaded machine (it needs CAP_SYS_NICE, e.g.
systemd's ``CPUSchedulingPolicy``/``LimitRTPRIO`` or root; refused, the loop runs as before and
``LoopTiming.priority`` says 0). It does not make the GIL come any sooner: a thread of the same
process that holds the GIL when the kernel preempts it for another process keeps the loop
waiting until it runs again (measured: ticks up to 15-45 ms late on a loaded 2-core machine).
:func:`raise_process_threads` puts the process's other threads in SCHED_FIFO too, at a
priority below the loop's, so a GIL holder is not preempted by other processes (the web side
then runs before everything in the normal class; its children start in the normal class).
"""

from __future__ import annotations

import bisect
import math
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from tracker.errors import ConfigError

SPIN_S = 5e-4
SWITCH_INTERVAL_S = 5e-4
MAX_BEHIND_S = 0.1
# Upper bounds of the tick-gap histogram's buckets, in periods (the last bucket is +inf).
GAP_BUCKETS = (0.5, 0.9, 1.1, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0, 1000.0)


def sleep_until(deadline_s: float, spin_s: float = SPIN_S) -> None:
    """Return at ``deadline_s`` (``time.perf_counter`` seconds): sleep, then busy-wait ``spin_s``."""
    while True:
        remaining = deadline_s - time.perf_counter()
        if remaining <= 0.0:
            return
        if remaining > spin_s:
            time.sleep(remaining - spin_s)
        else:
            while time.perf_counter() < deadline_s:
                pass
            return


@dataclass(frozen=True, slots=True)
class LoopTiming:
    """How well the loop keeps its clock (since it started; times in seconds)."""

    period_s: float
    ticks: int
    last_lateness_s: float
    max_lateness_s: float
    mean_lateness_s: float
    overruns: int
    restarts: int  # times the loop fell more than max_behind_s behind and started afresh
    running: bool
    in_thread: bool
    priority: int = 0  # the SCHED_FIFO priority the loop's thread got (0: the normal class)
    last_tick_age_s: float = math.inf  # since the latest tick started (inf before the first)
    gap_bounds_s: tuple[float, ...] = ()  # the gap histogram's bucket upper bounds (s)
    gap_counts: tuple[int, ...] = ()  # gaps per bucket (not cumulative; one more: over the last)
    gap_sum_s: float = 0.0  # sum of all gaps
    warm_up_ticks: int = 0  # the first ticks, left out of max_lateness_s and mean_lateness_s
    warm_up_max_lateness_s: float = 0.0  # the largest lateness among them


class TickStats:
    """Lateness bookkeeping shared by the thread loop and the event-loop (batch) runner.

    The first ``warm_up_ticks`` ticks are the loop's warm-up (the engine's first chunk compiles
    or loads its numba kernels: 10-15 s late with a cold cache): their largest lateness is kept
    apart, and the largest and mean lateness count from the tick after them, so a slow start
    does not stand as the loop's worst tick for the service's life. The counters (ticks,
    overruns, restarts, the gap histogram) count from the start: they only ever grow."""

    def __init__(self, period_s: float, warm_up_ticks: int = 0) -> None:
        self.period_s = float(period_s)
        self.warm_up_ticks = max(0, int(warm_up_ticks))
        self.warm_up_max = 0.0
        self.ticks = 0
        self.last = 0.0
        self.max = 0.0
        self.total = 0.0
        self.overruns = 0
        self.restarts = 0
        self.gap_bounds_s = tuple(b * self.period_s for b in GAP_BUCKETS)
        self.gap_counts = [0] * (len(GAP_BUCKETS) + 1)
        self.gap_sum_s = 0.0
        self.last_start_s = math.nan  # time.perf_counter() at the latest tick's start

    def record(self, lateness_s: float, start_s: float | None = None) -> None:
        """One tick, ``lateness_s`` after its due time; ``start_s`` (perf_counter) when it started."""
        late = max(0.0, lateness_s)
        if start_s is not None:
            if self.last_start_s == self.last_start_s:  # not NaN: there was a tick before
                gap = start_s - self.last_start_s
                self.gap_sum_s += gap
                self.gap_counts[bisect.bisect_left(self.gap_bounds_s, gap)] += 1
            self.last_start_s = start_s
        self.ticks += 1
        self.last = late
        if self.ticks <= self.warm_up_ticks:
            self.warm_up_max = max(self.warm_up_max, late)
        else:
            self.total += late
            self.max = max(self.max, late)
        if late >= self.period_s:
            self.overruns += 1

    def snapshot(self, running: bool, in_thread: bool, priority: int = 0) -> LoopTiming:
        warm = self.ticks - self.warm_up_ticks
        mean = self.total / warm if warm > 0 else 0.0
        start = self.last_start_s
        age = time.perf_counter() - start if start == start else math.inf
        return LoopTiming(self.period_s, self.ticks, self.last, self.max, mean, self.overruns,
                          self.restarts, running, in_thread, priority, age, self.gap_bounds_s,
                          tuple(self.gap_counts), self.gap_sum_s, self.warm_up_ticks, self.warm_up_max)


def raise_process_threads(priority: int) -> tuple[int, str | None]:
    """Put this process's threads that are in the normal class in SCHED_FIFO ``priority`` (1-99,
    Linux), with SCHED_RESET_ON_FORK (processes they start run in the normal class, nice reset).

    Threads started later inherit the class from the thread that starts them. A thread already
    in a real-time class (the loop's) keeps its own. Returns (threads moved, the refusal if any:
    without CAP_SYS_NICE or RLIMIT_RTPRIO nothing moves and the process runs as before).
    """
    if not 1 <= priority <= 99:
        raise ConfigError(f"thread priority {priority!r} must be in 1..99")
    try:
        policy = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
        tids = [int(t) for t in os.listdir(f"/proc/{os.getpid()}/task")]
    except (AttributeError, OSError) as exc:  # not Linux
        return 0, str(exc)
    moved, refusal = 0, None
    for tid in tids:
        try:
            if os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK != os.SCHED_OTHER:
                continue
            os.sched_setscheduler(tid, policy, os.sched_param(priority))
            moved += 1
        except ProcessLookupError:  # the thread ended meanwhile
            continue
        except OSError as exc:  # not allowed: the first refusal says it for all
            refusal = str(exc)
            break
    return moved, refusal


class PacedLoop:
    """Calls ``step()`` every ``period_s`` in a thread until ``step`` returns False or :meth:`stop`.

    ``on_exit(error)`` runs in the thread when the loop ends (``error`` is what ``step`` raised,
    or None).
    """

    def __init__(
        self,
        period_s: float,
        step: Callable[[], bool],
        *,
        on_exit: Callable[[BaseException | None], None] | None = None,
        spin_s: float = SPIN_S,
        max_behind_s: float = MAX_BEHIND_S,
        switch_interval_s: float | None = SWITCH_INTERVAL_S,
        priority: int = 0,
        name: str = "control-loop",
        warm_up_ticks: int = 0,
    ) -> None:
        if not (period_s > 0 and spin_s >= 0 and max_behind_s > 0):
            raise ConfigError(
                f"loop: period {period_s!r} s, spin {spin_s!r} s, max behind {max_behind_s!r} s")
        self.stats = TickStats(period_s, warm_up_ticks)
        self._step, self._on_exit = step, on_exit
        self._spin, self._max_behind, self._switch = spin_s, max_behind_s, switch_interval_s
        self._want_priority, self.priority = int(priority), 0
        self.priority_error: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Ask the loop to end after the current tick."""
        self._stop.set()

    def join(self, timeout_s: float | None = None) -> None:
        self._thread.join(timeout_s)

    def timing(self) -> LoopTiming:
        return self.stats.snapshot(self.running, True, self.priority)

    def _raise_priority(self) -> None:
        if self._want_priority <= 0:
            return
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self._want_priority))  # this thread
            self.priority = self._want_priority
        except (AttributeError, OSError) as exc:  # not Linux, or not allowed: run as before
            self.priority_error = str(exc)

    def _run(self) -> None:
        old_switch = sys.getswitchinterval()
        if self._switch is not None:
            sys.setswitchinterval(self._switch)
        error: BaseException | None = None
        period = self.stats.period_s
        self._raise_priority()
        try:
            # Ticks fall on the grid of whole periods of perf_counter: a driver that paces its
            # own samples on that grid (tracker.drivers.serial_motor) then agrees with the loop.
            due = math.ceil(time.perf_counter() / period) * period
            while not self._stop.is_set():
                sleep_until(due, self._spin)
                start = time.perf_counter()
                if start - due > self._max_behind:
                    self.stats.restarts += 1
                    self.stats.record(start - due, start)
                    due = math.floor(start / period) * period
                else:
                    self.stats.record(start - due, start)
                if not self._step():
                    break
                due += period
        except BaseException as exc:  # handed to on_exit: the engine reports it on its side
            error = exc
        finally:
            if self._switch is not None:
                sys.setswitchinterval(old_switch)
            if self._on_exit is not None:
                self._on_exit(error)
