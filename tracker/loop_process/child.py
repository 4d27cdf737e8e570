"""The control loop's own process: builds the engine and its driver, takes the service's calls
over the pipe, and runs the loop with the calls handled between chunks.

:func:`serve` is the process's target (``multiprocessing``, spawned: the service has threads
that must not be forked). Before the loop runs, calls are answered as they come (the service
restores its stored gains and models then); once it runs, the loop's thread answers them after
each chunk, those that came during the chunk and then those that come while it waits for the
next tick (until ``SPIN_S`` before it is due; at most ``CALLS_PER_CHUNK`` each), so a call
waits for the chunk in progress at most, and the only thread running Python in this process is
the loop's (the main thread waits in the event loop's poll). After every chunk it writes the
snapshot, status and timing to the shared block (:mod:`tracker.loop_process.shared`).

Safety stays here: the engine checks every target and rate against its soft limits and the
driver its own; when the service's end of the pipe closes (the service died or stopped) the loop
stops, the driver is disabled (the axes get 0 V) and closed, and the process exits. SIGTERM
stops it the same way; SIGINT (a Ctrl-C in the service's terminal reaches the whole process
group) is ignored: the service decides when its loop stops.
"""

from __future__ import annotations

import asyncio
import gc
import inspect
import math
import select
import signal
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from tracker.engine import Engine
from tracker.errors import ConfigError
from tracker.loop_process.shared import SharedLoop
from tracker.loop_process.wire import Call, CarriedError, Ready, Reply
from tracker.realtime import SPIN_S
from tracker.targets import Target
from tracker.telemetry import TelemetrySnapshot

CALLS_PER_CHUNK = 4  # a burst of calls is spread over ticks, not run in one


class PushedSource:
    """A target source reading the target the service pushed into the shared block."""

    def __init__(self, name: str, shared: SharedLoop) -> None:
        self.name = name
        self._shared = shared

    def target_at(self, t_s: float) -> Target | None:
        return self._shared.read_target()


def command_table(engine: Engine, shared: SharedLoop) -> dict[str, Callable[..., Any]]:
    """What the service may call, by name (nothing else is reachable over the pipe)."""
    drv = engine.driver

    def set_source(name: str | None) -> None:
        engine.set_target_source(None if name is None else PushedSource(name, shared))

    return {
        "point": engine.point, "release": engine.release, "jog": engine.jog,
        "set_tracking": engine.set_tracking, "set_gains": engine.set_gains, "gains": engine.gains,
        "set_model": engine.set_model, "model": engine.model, "limits": engine.limits,
        "recent_motion": engine.recent_motion, "observed": engine.observed,
        "start_recording": engine.start_recording, "stop_recording": engine.stop_recording,
        "clear_faults": drv.clear_faults, "enable": drv.enable, "disable": drv.disable,
        "latch_fault": getattr(drv, "latch_fault", _no_latch),
        "set_target_source": set_source, "stop": engine.stop,
    }


def _no_latch(message: str) -> None:
    raise ConfigError(f"this driver latches no fault on request ({message!r})")


def driver_description(engine: Engine) -> dict[str, Any]:
    describe = getattr(engine.driver, "describe", None)
    if callable(describe):
        out: dict[str, Any] = describe()
        return out
    return {"kind": "sim", "url": "sim", "state": "running"}


class LoopServer:
    """Answers the service's calls and publishes the engine's state (see the module docstring)."""

    def __init__(self, engine: Engine, shared: SharedLoop, conn: Connection) -> None:
        self.engine, self.shared, self.conn = engine, shared, conn
        self.table = command_table(engine, shared)
        self.parent_gone = False
        self._wake_s = math.nan  # perf_counter: stop waiting for calls (SPIN_S before the next tick)

    def answer(self, call: Call) -> None:
        fn = self.table.get(call.method)
        try:
            if fn is None:
                raise ConfigError(f"the control loop's process has no call {call.method!r}")
            reply = Reply(call.call_id, fn(*call.args, **call.kwargs))
        except Exception as exc:  # carried back to the caller as the same type
            reply = Reply(call.call_id, error=CarriedError.of(exc))
        self.publish_status()  # a status read right after the reply sees the call's effect
        self.conn.send(reply)

    def publish_status(self, snap: TelemetrySnapshot | None = None) -> None:
        e = self.engine
        timing = e.timing()
        age = timing.last_tick_age_s
        last_start = time.perf_counter() - age if math.isfinite(age) else math.nan
        # The paced loop's next due time: this tick's (its start less its lateness) + a period.
        self._wake_s = (last_start - timing.last_lateness_s + timing.period_s - SPIN_S
                        if timing.in_thread else math.nan)
        if snap is None:
            self.shared.write_status(e.status(), e.driver.enabled, timing, last_start,
                                     self.shared.read_text().source)
        else:
            self.shared.write_chunk(snap, e.status(), e.driver.enabled, timing, last_start)

    def serve_until_run(self) -> dict[str, Any] | None:
        """Answer calls until "run" (its arguments: realtime, duration_s) or "stop" / the
        service gone (None)."""
        while True:
            try:
                call = self.conn.recv()
            except (EOFError, OSError):
                self.parent_gone = True
                return None
            if call.method == "run":
                self.conn.send(Reply(call.call_id))
                return dict(call.kwargs)
            if call.method == "stop":
                self.conn.send(Reply(call.call_id))
                return None
            self.answer(call)

    def after_chunk(self, snap: TelemetrySnapshot) -> None:
        """The loop's thread, between chunks: publish, then answer the calls that came."""
        self.publish_status(snap)
        wake_s = self._wake_s
        try:
            for _ in range(CALLS_PER_CHUNK):  # those that came during the chunk
                if not self.conn.poll(0):
                    break
                self.answer(self.conn.recv())
            for _ in range(CALLS_PER_CHUNK):  # those that come before the next tick
                remaining_s = wake_s - time.perf_counter()
                # select's timeout is in µs (Connection.poll rounds it up to whole ms: ticks
                # then started up to 1 ms late)
                if not remaining_s > 0.0 or not select.select([self.conn], [], [], remaining_s)[0]:
                    break
                self.answer(self.conn.recv())
        except (EOFError, OSError):  # the service is gone: nobody may steer; stop
            self.parent_gone = True
            self.engine.stop()


def serve(conn: Connection, build: Callable[[Any], Engine], arg: Any, shm_name: str) -> None:
    """The process's body: build, answer, run, stop the axes, exit."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit)  # before the loop runs; then it stops the loop
    shared = SharedLoop.attach(shm_name)
    try:
        engine = build(arg)
    except Exception as exc:
        conn.send(Reply(0, error=CarriedError.of(exc)))
        shared.close()
        return
    gc.collect()
    gc.freeze()  # start-up's objects out of the collector's sight (app/service.py says why)
    server = LoopServer(engine, shared, conn)
    server.publish_status()
    conn.send(Ready(engine.config, engine.driver.sample_period_s,
                    max(1, round(engine.config.chunk_s / engine.driver.sample_period_s))
                    * engine.driver.sample_period_s,
                    driver_description(engine)))
    try:
        run = server.serve_until_run()
        if run is not None:
            asyncio.run(_run(engine, server, run))
            server.publish_status()
    finally:
        stop_axes(engine)
        shared.close()


def _exit(signum: int, frame: Any) -> None:  # noqa: ANN401 - a signal handler
    raise SystemExit(0)


async def _run(engine: Engine, server: LoopServer, run: dict[str, Any]) -> None:
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, engine.stop)
    await engine.run(realtime=bool(run.get("realtime", True)), duration_s=run.get("duration_s"),
                     on_chunk=server.after_chunk)


def stop_axes(engine: Engine) -> None:
    """Disable the driver (0 V on every axis) and close its link, whatever else failed."""
    try:
        engine.driver.disable()
    finally:
        close = getattr(engine.driver, "close", None)
        if close is not None:
            done = close()
            if inspect.isawaitable(done):
                asyncio.run(_wait(done))


async def _wait(done: Any) -> None:
    await done
