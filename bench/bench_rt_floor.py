"""The machine's own floor for a 1 kHz real-time loop: how late can a tick be with no Python
service around it at all?

A lone thread in a process of its own — nothing of ``tracker/`` or ``app/``, no other thread, no
interpreter lock to wait for — sleeps to each 1 ms deadline (sleep, then a 0.5 ms busy-wait, as
the control loop does), optionally in SCHED_FIFO and pinned to one CPU, and records how late each
tick started. ``--busy N`` starts N busy processes in the normal class beside it (the load a
workbench job or another program puts on the machine).

Whatever this prints is the best the console's control loop can do on this machine: compare
``bench/bench_loop_under_load.py``'s "ticks > 2 ms late" with it (docs/console.md).

    python bench/bench_rt_floor.py --seconds 20 --priority 50 [--cpu 1] [--busy 2]
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import time


def _busy(stop_at_s: float) -> None:
    x = 0
    while time.time() < stop_at_s:
        x += 1


def _wait_until(deadline_s: float, spin_s: float) -> None:
    remaining = deadline_s - time.perf_counter()
    if remaining > spin_s:
        time.sleep(remaining - spin_s)
    while time.perf_counter() < deadline_s:
        pass


def measure(seconds: float, period_s: float, spin_s: float) -> list[float]:
    """Lateness (s) of each tick over ``seconds`` at ``period_s``."""
    due = math.ceil(time.perf_counter() / period_s) * period_s
    end = due + seconds
    late: list[float] = []
    while due < end:
        _wait_until(due, spin_s)
        late.append(time.perf_counter() - due)
        due += period_s
    return late


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--period-ms", type=float, default=1.0)
    ap.add_argument("--spin-ms", type=float, default=0.5)
    ap.add_argument("--priority", type=int, default=50, help="SCHED_FIFO priority (0: normal class)")
    ap.add_argument("--cpu", type=int, default=-1, help="pin the thread to this CPU (-1: any)")
    ap.add_argument("--busy", type=int, default=0, help="busy normal-class processes beside it")
    args = ap.parse_args()

    got = "normal class"
    if args.priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.priority))
            got = f"SCHED_FIFO {args.priority}"
        except OSError as exc:
            got = f"normal class (SCHED_FIFO refused: {exc})"
    if args.cpu >= 0:
        os.sched_setaffinity(0, {args.cpu})
    ctx = mp.get_context("spawn")
    stop_at = time.time() + args.seconds + 2.0
    busy = [ctx.Process(target=_busy, args=(stop_at,), daemon=True) for _ in range(args.busy)]
    for p in busy:
        p.start()
    time.sleep(0.5 if busy else 0.0)
    late = sorted(measure(args.seconds, args.period_ms / 1e3, args.spin_ms / 1e3))
    for p in busy:
        p.join()
    n = len(late)
    ms = [x * 1e3 for x in late]
    print(f"{n} ticks at {args.period_ms:g} ms, {got}, cpu {'any' if args.cpu < 0 else args.cpu}, "
          f"{args.busy} busy processes beside; load average {os.getloadavg()[0]:.1f}")
    print(f"  lateness: median {ms[n // 2]:.3f} ms, p99 {ms[int(n * 0.99)]:.3f} ms, "
          f"p99.9 {ms[int(n * 0.999)]:.3f} ms, max {ms[-1]:.2f} ms")
    print(f"  ticks > 0.5 ms late: {sum(x > 0.5 for x in ms)}; > 2 ms late: {sum(x > 2.0 for x in ms)} "
          f"({100.0 * sum(x > 2.0 for x in ms) / n:.3f} %)")


if __name__ == "__main__":
    main()
