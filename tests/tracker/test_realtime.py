"""The control loop's own clock: ticks on the perf_counter grid, lateness and overruns kept,
the end of the loop handed back, a refused real-time priority harmless."""

import math
import sys
import time

import pytest

from tracker.realtime import PacedLoop, sleep_until


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
