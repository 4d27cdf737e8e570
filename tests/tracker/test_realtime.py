"""The control loop's own clock: ticks on the perf_counter grid, lateness and overruns kept,
the end of the loop handed back, a refused real-time priority harmless."""

import contextlib
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable

import pytest

from tracker.errors import ConfigError
from tracker.realtime import PacedLoop, raise_process_threads, sleep_until


def test_sleep_until_returns_at_the_deadline_not_before() -> None:
    deadline = time.perf_counter() + 0.02
    sleep_until(deadline)
    assert 0.0 <= time.perf_counter() - deadline < 0.05


def test_ticks_fall_on_the_grid_and_the_loop_ends_when_step_says_so() -> None:
    stamps: list[float] = []
    ended: list[BaseException | None] = []

    def step() -> bool:
        stamps.append(time.perf_counter())
        return len(stamps) < 20

    loop = PacedLoop(0.005, step, on_exit=ended.append)
    old = sys.getswitchinterval()
    loop.start()
    loop.join(5.0)
    assert not loop.running and ended == [None] and len(stamps) == 20
    assert sys.getswitchinterval() == old  # restored when the loop ends
    k = [math.floor(t / 0.005) for t in stamps]  # a tick starts after its grid point, < a period late
    assert k == list(range(k[0], k[0] + 20)) or loop.timing().overruns > 0
    t = loop.timing()
    assert t.ticks == 20 and t.in_thread and 0.0 <= t.last_lateness_s <= t.max_lateness_s
    assert stamps[-1] - stamps[0] == pytest.approx(19 * 0.005, abs=0.05)


def test_a_late_tick_counts_as_an_overrun_and_the_loop_catches_up() -> None:
    stamps: list[float] = []

    def step() -> bool:
        stamps.append(time.perf_counter())
        if len(stamps) == 3:
            time.sleep(0.035)  # a stall of 3.5 periods: the next two start over a period late
        return len(stamps) < 12

    loop = PacedLoop(0.01, step)
    loop.start()
    loop.join(5.0)
    t = loop.timing()
    assert t.overruns >= 2 and t.max_lateness_s >= 0.02 and t.restarts == 0
    assert stamps[-1] - stamps[0] == pytest.approx(11 * 0.01, abs=0.03)  # caught up: no time lost


def test_an_error_in_step_ends_the_loop_and_is_handed_over() -> None:
    ended: list[BaseException | None] = []

    def step() -> bool:
        raise RuntimeError("boom")

    loop = PacedLoop(0.005, step, on_exit=ended.append)
    loop.start()
    loop.join(5.0)
    assert isinstance(ended[0], RuntimeError)


def test_a_real_time_priority_is_taken_or_its_refusal_noted() -> None:
    loop = PacedLoop(0.005, lambda: False, priority=10)
    loop.start()
    loop.join(5.0)
    assert (loop.priority == 10) != (loop.priority_error is not None)


def test_tick_gaps_are_counted_in_period_buckets_and_a_stuck_tick_shows_its_age() -> None:
    """Issue 11 item 7: the service exports tick gaps as a histogram and /health needs the age
    of the latest tick; a stall of 4 periods is one gap of about 4 periods, the sum of the
    gaps spans first to last tick, and while a tick is stuck its age grows past the stall."""
    stamps: list[float] = []
    stuck_age: list[float] = []
    loop: PacedLoop

    def step() -> bool:
        stamps.append(time.perf_counter())
        if len(stamps) == 5:
            time.sleep(0.04)
            stuck_age.append(loop.timing().last_tick_age_s)  # read during the stuck tick
        return len(stamps) < 15

    loop = PacedLoop(0.01, step)
    assert loop.timing().last_tick_age_s == math.inf  # no tick yet
    loop.start()
    loop.join(5.0)
    t = loop.timing()
    assert sum(t.gap_counts) == t.ticks - 1 == 14
    assert t.gap_sum_s == pytest.approx(stamps[-1] - stamps[0], abs=2e-3)
    assert t.gap_bounds_s[2] == pytest.approx(0.011)  # 1.1 periods
    gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    longest = max(gaps)
    assert 0.04 <= longest < 0.1
    bucket = next(i for i, b in enumerate(t.gap_bounds_s) if longest <= b)
    assert t.gap_counts[bucket] >= 1 and t.gap_bounds_s[bucket] >= 0.04
    assert stuck_age and stuck_age[0] >= 0.04
    assert 0.0 <= t.last_tick_age_s < 5.0


def _normal_again() -> None:
    """Every thread of this process back in the normal class (the test moved them)."""
    for name in os.listdir(f"/proc/{os.getpid()}/task"):
        with contextlib.suppress(OSError):
            os.sched_setscheduler(int(name), os.SCHED_OTHER, os.sched_param(0))


@pytest.mark.skipif(not hasattr(os, "SCHED_RESET_ON_FORK"), reason="Linux scheduling classes")
def test_the_process_threads_go_real_time_below_the_loop_and_children_start_normal() -> None:
    """The service's threads at a low SCHED_FIFO priority: a normal-class thread moves, a thread
    already real-time (the loop's) keeps its priority, a thread or process started afterwards
    begins in the normal class (SCHED_RESET_ON_FORK: worker processes never inherit it)."""
    go, ids = threading.Event(), {}

    def wait(name: str) -> None:
        ids[name] = threading.get_native_id()
        go.wait(10.0)

    plain = threading.Thread(target=wait, args=("plain",))
    plain.start()
    loop = PacedLoop(0.005, lambda: not go.is_set(), priority=20)
    loop.start()
    try:
        assert poll_until(lambda: "plain" in ids and loop.timing().ticks > 0)
        if loop.priority != 20:
            pytest.skip(f"real-time priorities refused here: {loop.priority_error}")
        moved, refusal = raise_process_threads(5)
        assert refusal is None and moved >= 2  # at least this thread and `plain`
        fifo = os.SCHED_FIFO
        assert os.sched_getscheduler(ids["plain"]) & ~os.SCHED_RESET_ON_FORK == fifo
        assert os.sched_getparam(ids["plain"]).sched_priority == 5
        assert os.sched_getparam(0).sched_priority == 5
        loop_tid = loop._thread.native_id
        assert loop_tid is not None and os.sched_getparam(loop_tid).sched_priority == 20
        later = threading.Thread(target=wait, args=("later",))
        later.start()
        assert poll_until(lambda: "later" in ids)
        assert os.sched_getscheduler(ids["later"]) == os.SCHED_OTHER
        child = subprocess.run([sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"],
                               capture_output=True, text=True, timeout=60, check=True)
        assert int(child.stdout) == os.SCHED_OTHER
        with pytest.raises(ConfigError, match="1..99"):
            raise_process_threads(0)
    finally:
        go.set()
        _normal_again()
        plain.join(5.0)
        loop.join(5.0)


def poll_until(fn: Callable[[], bool], deadline_s: float = 5.0) -> bool:
    end = time.monotonic() + deadline_s
    while not fn() and time.monotonic() < end:
        time.sleep(0.005)
    return fn()


def test_the_warm_up_ticks_lateness_is_kept_apart_from_the_loops() -> None:
    """Bug: a cold numba cache made the engine's first chunk 10-15 s late, and max_lateness in
    the status kept that for the service's life. The warm-up's worst is reported apart."""
    stamps: list[float] = []

    def step() -> bool:
        stamps.append(time.perf_counter())
        if len(stamps) == 1:
            time.sleep(0.06)  # the first chunk compiles: the second tick starts ~50 ms late
        if len(stamps) == 6:
            time.sleep(0.025)  # a later stall: the seventh tick starts ~15 ms late
        return len(stamps) < 10

    loop = PacedLoop(0.01, step, warm_up_ticks=3)
    loop.start()
    loop.join(5.0)
    t = loop.timing()
    assert t.ticks == 10 and t.warm_up_ticks == 3
    assert t.warm_up_max_lateness_s >= 0.045
    assert 0.01 <= t.max_lateness_s < 0.045  # the later stall, not the warm-up's
    assert t.overruns >= 2  # the counters count from the start


def test_without_a_warm_up_every_tick_counts() -> None:
    from tracker.realtime import TickStats

    stats = TickStats(0.01)
    for late in (0.5, 0.001, 0.002):
        stats.record(late)
    t = stats.snapshot(True, True)
    assert t.max_lateness_s == 0.5 and t.mean_lateness_s == pytest.approx(0.503 / 3)
    warm = TickStats(0.01, warm_up_ticks=1)
    for late in (0.5, 0.001, 0.002):
        warm.record(late)
    t = warm.snapshot(True, True)
    assert t.warm_up_max_lateness_s == 0.5 and t.max_lateness_s == 0.002
    assert t.mean_lateness_s == pytest.approx(0.0015) and t.ticks == 3
