"""Control ticks and telemetry frames of the console under load: the service on 127.0.0.1 (the
twin), workbench uploads and diagnoses running, 50 telemetry WebSocket viewers and a burst of
REST calls. Prints the largest gap between control ticks and between telemetry frames, ticks
late by more than 2 ms and overruns, idle and under load.

    python bench/bench_loop_under_load.py [--tree PATH] [--chunk-ms 10] [--seconds 20]
                                          [--viewers 50] [--rest 600] [--diagnoses 2]
                                          [--priority 50] [--service-priority 10]
                                          [--camera [--camera-rate-hz 25]] [--alone]
                                          [--loop-process]

Ticks: the largest gap between tick starts, each tick's lateness against its due time (the
loop's deadlines replayed: p99, max, how many over 2 ms), overruns, the longest tick body; the
service's garbage collections. ``--camera`` steers ``tracker camera-emulator`` (its own
process) over VISCA on UDP and adds the command cycles' gaps and missed periods; ``--alone``
runs the same engine on the twin alone in a process of its own, under the same load (what a
loop in its own process would get); ``--web-fifo N`` (diagnostic) moves the service's other
threads into SCHED_FIFO N from outside at the load's start. ``--loop-process`` runs the
service with ``loop_process = true`` (the twin's engine in a spawned process of its own): its
ticks are time-stamped there by the same probe, loaded through a ``sitecustomize`` in the
spawned processes.

``--tree`` runs the service from another checkout (e.g. main, for the figures before); the
service gets ``TRACKER_CONTROL_CHUNK_MS`` (a tree without that setting ignores it). Control
ticks are time-stamped inside the service by a probe that wraps ``Engine.step_chunk`` (works on
any tree); perf_counter is CLOCK_MONOTONIC, comparable between the two processes. Everything
is bounded: counts and seconds, loopback only. The viewers run in this process on the same
machine, so their frame gaps include this process's own delays.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import websockets

ROOT = Path(__file__).resolve().parent.parent
PROBE = """
import array, atexit, os, sys, time
import tracker.engine as engine_module
_ticks = array.array("d")
_step = engine_module.Engine.step_chunk
_ends = array.array("d")
def step_chunk(self):
    _ticks.append(time.perf_counter())
    try:
        return _step(self)
    finally:
        _ends.append(time.perf_counter())
engine_module.Engine.step_chunk = step_chunk
if os.environ.get("BENCH_SPIN_S"):  # --spin-ms: the loop's busy-wait before each tick
    import tracker.realtime as realtime_module
    realtime_module.PacedLoop.__init__.__kwdefaults__["spin_s"] = float(os.environ["BENCH_SPIN_S"])
_gc = array.array("d")  # garbage collections: start, duration, generation (all threads)
_gc_start = [0.0]
def _on_gc(phase, info):
    if phase == "start":
        _gc_start[0] = time.perf_counter()
    else:
        _gc.extend((_gc_start[0], time.perf_counter() - _gc_start[0], info["generation"]))
import gc
gc.callbacks.append(_on_gc)
_cmds = array.array("d")  # a PTZ camera's command cycles (each sends one steering command)
try:
    import tracker.drivers.visca as visca_module
    _steer = visca_module.ViscaCamera._steer
    async def _steer_probe(self):
        _cmds.append(time.perf_counter())
        await _steer(self)
    visca_module.ViscaCamera._steer = _steer_probe
except ImportError:  # a tree without the camera driver
    pass
def _dump():
    with open(os.environ["BENCH_TICKS"], "wb") as f:
        array.array("d", [len(_ticks), len(_ends), len(_cmds)]).tofile(f)
        _ticks.tofile(f)
        _ends.tofile(f)
        _cmds.tofile(f)
        _gc.tofile(f)
if __name__ == "__main__":  # not in the service's spawned worker processes
    import signal
    signal.signal(signal.SIGUSR1, lambda *_: _dump())  # the bench asks before it stops the service
    atexit.register(_dump)
    from tracker.cli import main
    sys.exit(main(sys.argv[1:]))
"""

# --alone: the same engine on the twin, alone in a process of its own (no web side), run during
# the bench under the same load: what a control loop in its own process would get here.
ALONE = """
import asyncio, os, signal, sys, time
sys.argv = [sys.argv[0]]
exec(open(os.environ["BENCH_PROBE"]).read().split("if __name__")[0])
from tracker.drivers.sim import SimDriver
from tracker.engine import Engine, EngineConfig
engine = Engine(SimDriver(), EngineConfig(chunk_s=float(os.environ["BENCH_CHUNK_S"]),
                                          loop_priority=int(os.environ["BENCH_PRIORITY"])))
async def main():
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, engine.stop)
    await engine.run(realtime=True)
asyncio.run(main())
_dump()
"""


# --loop-process: the probe in the spawned processes (the loop's process; the workers record no
# tick), dumped on SIGUSR1 to BENCH_TICKS.<pid>.
CHILD_PROBE = """
import os, sys
if os.environ.get("BENCH_TICKS") and "--multiprocessing-fork" in sys.argv:
    os.environ["BENCH_TICKS"] = os.environ["BENCH_TICKS"] + "." + str(os.getpid())
    exec(open(os.environ["BENCH_PROBE"]).read().split("if __name__")[0])
    import signal
    signal.signal(signal.SIGUSR1, lambda *_: _dump())
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def measurement_csv(seconds: float) -> str:
    """A closed-loop measurement of the pan twin with ripple the base model lacks."""
    from tracker.plant.model import AxisModel
    from tracker.workbench.experiments.experiments import generate_measurement
    from tracker.workbench.measurements.data import format_log

    truth = AxisModel.for_axis("pan", ["ripple"], {"ripple.amplitude": 0.01, "ripple.cycles_per_rev": 12.0})
    return str(format_log(generate_measurement(truth, duration_s=seconds, seed=4)))


class Viewer:
    def __init__(self) -> None:
        self.arrivals: list[float] = []


async def viewer(url: str, key: str, v: Viewer, stop: asyncio.Event) -> None:
    async with websockets.connect(url, additional_headers={"X-API-Key": key}, max_queue=None) as ws:
        await ws.recv()  # hello
        while not stop.is_set():
            try:
                msg = await asyncio.wait_for(ws.recv(), timeout=0.5)
            except TimeoutError:
                continue
            if isinstance(msg, str) and msg.startswith('{"type":"frame"'):
                v.arrivals.append(time.perf_counter())


async def post_retrying(c: httpx.AsyncClient, url: str, **kw: Any) -> httpx.Response:
    """POST, waiting out 429s (the heavy pool is shared with the burst's gains calls) as a
    client would: Retry-After, at most 60 tries."""
    for _ in range(60):
        r = await c.post(url, **kw)
        if r.status_code != 429:
            break
        await asyncio.sleep(min(2.0, float(r.headers.get("retry-after", "0.5") or 0.5)))
    r.raise_for_status()
    return r


async def workbench(api: str, h: dict[str, str], csv: str, n: int, log: list[str]) -> None:
    async with httpx.AsyncClient(timeout=300.0) as c:
        for i in range(n):
            t0 = time.perf_counter()
            r = await post_retrying(
                c,
                f"{api}/workbench/measurements",
                headers=h,
                data={"axis": "pan"},
                files={"file": (f"bench{i}.csv", csv.encode(), "text/csv")},
            )
            mid = r.json()["id"]
            t1 = time.perf_counter()
            r = await post_retrying(c, f"{api}/workbench/measurements/{mid}/diagnose", headers=h, json={})
            log.append(
                f"upload {t1 - t0:.1f} s, diagnose {time.perf_counter() - t1:.1f} s (started at {t0:.3f})"
            )


async def rest_burst(api: str, h: dict[str, str], n: int, concurrency: int, refused: list[int]) -> float:
    """``n`` calls, ``concurrency`` at a time; 429s (a tree that caps heavy requests) are counted."""
    paths = ["/status", "/presets", "/axes/pan/gains", "/jobs", "/workbench/measurements"]
    sem = asyncio.Semaphore(concurrency)
    t0 = time.perf_counter()
    async with httpx.AsyncClient(timeout=60.0) as c:

        async def one(i: int) -> None:
            async with sem:
                if i % 10 == 9:
                    r = await c.put(f"{api}/tracking", headers=h, json={"enabled": i % 20 == 9})
                else:
                    r = await c.get(api + paths[i % len(paths)], headers=h)
                if r.status_code == 429:
                    refused.append(i)
                else:
                    r.raise_for_status()

        await asyncio.gather(*(one(i) for i in range(n)))
    return time.perf_counter() - t0


def read_ticks(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The probe's dump: (tick starts, tick ends, camera command cycles, garbage collections as
    rows of start, duration, generation), perf_counter seconds."""
    raw = np.frombuffer(path.read_bytes(), dtype=np.float64) if path.exists() else np.zeros(3)
    n_t, n_e, n_c = (int(x) for x in raw[:3])
    a, b, c = 3 + n_t, 3 + n_t + n_e, 3 + n_t + n_e + n_c
    gcs = raw[c:]
    return raw[3:a], raw[a:b], raw[b:c], gcs[: gcs.size // 3 * 3].reshape(-1, 3)


def gc_figures(gcs: np.ndarray, t0: float, t1: float) -> dict[str, float]:
    """The service's garbage collections in [t0, t1] (a collection holds the interpreter lock)."""
    sel = gcs[(gcs[:, 0] >= t0) & (gcs[:, 0] <= t1)] if gcs.size else gcs
    out: dict[str, float] = {"collections": int(sel.shape[0])}
    for gen in (0, 1, 2):
        g = sel[sel[:, 2] == gen] if sel.size else sel
        out[f"gen{gen}"] = int(g.shape[0])
        out[f"gen{gen}_max_ms"] = 1e3 * float(g[:, 1].max()) if g.size else 0.0
    return out


def command_figures(cmds: np.ndarray, t0: float, t1: float, period_s: float) -> dict[str, float]:
    """A PTZ camera's command cycles in [t0, t1]: a *missed period* is a gap of two periods or
    more (a whole period passed without a command); *late* a gap over 1.5 periods."""
    sel = cmds[(cmds >= t0) & (cmds <= t1)]
    gaps = np.diff(sel)
    if gaps.size == 0:
        return {"commands": int(sel.size)}
    return {
        "commands": int(sel.size),
        "rate_hz": float(sel.size / (t1 - t0)),
        "max_gap_ms": 1e3 * float(gaps.max()),
        "p99_gap_ms": 1e3 * float(np.percentile(gaps, 99)),
        "late_1.5_periods": int(np.sum(gaps > 1.5 * period_s)),
        "missed_periods": int(np.sum(np.clip(np.floor(gaps / period_s + 1e-9) - 1, 0, None))),
    }


def boost_threads(pid: int, priority: int) -> int:
    """Diagnostic: put the service's threads that run in the normal class (all but the loop's
    when it has its SCHED_FIFO priority) in SCHED_FIFO ``priority``; how many were moved."""
    moved = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        tid = int(task.name)
        try:
            if os.sched_getscheduler(tid) == os.SCHED_OTHER:
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
                moved += 1
        except OSError:
            pass
    return moved


def lateness(starts: np.ndarray, period_s: float, max_behind_s: float = 0.1) -> np.ndarray:
    """Each tick's lateness (s), its due times replayed as tracker.realtime.PacedLoop sets them:
    one period after the previous due time, or, more than ``max_behind_s`` behind, afresh on
    the grid point before the tick (a restart). The first tick is due at the grid point before it."""
    late = np.empty(starts.size)
    due = np.floor(starts[0] / period_s) * period_s if starts.size else 0.0
    for i, start in enumerate(starts):
        if i:
            due += period_s
        if start - due > max_behind_s:
            late[i] = start - due
            due = np.floor(start / period_s) * period_s
        else:
            late[i] = max(0.0, start - due)
    return late


def tick_figures(
    ticks: np.ndarray, ends: np.ndarray, t0: float, t1: float, period_s: float
) -> dict[str, float]:
    mask = (ticks >= t0) & (ticks <= t1)
    sel = ticks[mask]
    gaps = np.diff(sel)
    if gaps.size == 0:
        return {"ticks": 0}
    body = ends[: ticks.size][mask[: ends.size]] - sel[: int(np.sum(mask[: ends.size]))]
    late = lateness(sel, period_s)
    return {
        "ticks": int(sel.size),
        "max_gap_ms": 1e3 * float(gaps.max()),
        "p99_gap_ms": 1e3 * float(np.percentile(gaps, 99)),
        "late_2ms": int(np.sum(gaps > period_s + 2e-3)),
        "overruns": int(np.sum(gaps > 2 * period_s)),
        "p99_late_ms": 1e3 * float(np.percentile(late, 99)),
        "max_late_ms": 1e3 * float(late.max()),
        "due_late_2ms": int(np.sum(late > 2e-3)),
        "max_body_ms": 1e3 * float(body.max()) if body.size else float("nan"),
        "p99_body_ms": 1e3 * float(np.percentile(body, 99)) if body.size else float("nan"),
        "drift_ms": 1e3 * float(late[-1]),
    }


def frame_figures(viewers: list[Viewer], t0: float, t1: float) -> dict[str, float]:
    gaps = []
    per_viewer_max = []
    frames = 0
    for v in viewers:
        a = np.asarray(v.arrivals)
        a = a[(a >= t0) & (a <= t1)]
        frames += a.size
        if a.size > 1:
            g = np.diff(a)
            gaps.append(g)
            per_viewer_max.append(g.max())
    if not gaps:
        return {"frames": frames}
    all_gaps = np.concatenate(gaps)
    return {
        "frames": frames,
        "rate_hz_per_viewer": frames / max(len(viewers), 1) / (t1 - t0),
        "max_gap_ms": 1e3 * float(all_gaps.max()),
        "p99_gap_ms": 1e3 * float(np.percentile(all_gaps, 99)),
        "median_viewer_max_gap_ms": 1e3 * float(np.median(per_viewer_max)),
    }


async def bench(args: argparse.Namespace, api: str, ws_url: str, key: str, csv: str) -> dict[str, Any]:
    h = {"X-API-Key": key}
    out: dict[str, Any] = {}
    await asyncio.sleep(2.0)  # the engine settles
    t_idle0 = time.perf_counter()
    await asyncio.sleep(args.idle_seconds)
    out["idle"] = (t_idle0, time.perf_counter())
    stop = asyncio.Event()
    views = [Viewer() for _ in range(args.viewers)]
    tasks = [asyncio.create_task(viewer(ws_url, key, v, stop)) for v in views]
    await asyncio.sleep(1.0)  # all connected
    log: list[str] = []
    if args.web_fifo:
        out["boosted"] = boost_threads(args.pid, args.web_fifo)
    t_load0 = time.perf_counter()
    job = asyncio.create_task(workbench(api, h, csv, args.diagnoses, log))
    refused: list[int] = []
    rest_s = await rest_burst(api, h, args.rest, 20, refused)
    out["refused"] = len(refused)
    try:
        await asyncio.wait_for(
            asyncio.shield(job), timeout=max(0.0, args.seconds - (time.perf_counter() - t_load0))
        )
    except TimeoutError:
        pass
    t_load1 = time.perf_counter()
    out["load"] = (t_load0, t_load1)
    out["job_done"] = job.done()
    out["rest_s"] = rest_s
    out["log"] = log
    async with httpx.AsyncClient(timeout=30.0) as c:
        status = (await c.get(f"{api}/status", headers=h)).json()
        out["status_loop"], out["status_driver"] = status.get("loop"), status.get("driver")
        out["status_faults"] = status.get("faults")
    stop.set()
    await asyncio.gather(*tasks, return_exceptions=True)
    try:  # let the service finish its diagnosis before it is stopped (bounded)
        await asyncio.wait_for(job, timeout=60.0)
    except (TimeoutError, httpx.HTTPError):
        pass
    out["viewers"] = views
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", default=str(ROOT), help="checkout to run the service from")
    parser.add_argument("--chunk-ms", type=float, default=10.0, help="the control tick (ms)")
    parser.add_argument("--priority", type=int, default=0, help="SCHED_FIFO priority of the loop thread")
    parser.add_argument("--spin-ms", type=float, default=None,
                        help="the loop's busy-wait before each tick (default: the tree's own)")
    parser.add_argument("--service-priority", type=int, default=0,
                        help="service_threads_priority: SCHED_FIFO for the service's other threads")
    parser.add_argument(
        "--web-fifo", type=int, default=0,
        help="diagnostic: SCHED_FIFO priority for the service's other threads at the load's start")
    parser.add_argument("--alone", action="store_true",
                        help="also run the same engine alone in a process of its own, under the same load")
    parser.add_argument("--loop-process", action="store_true",
                        help="loop_process = true: the twin's engine in a process of its own")
    parser.add_argument("--camera", action="store_true",
                        help="steer an emulated PTZ camera (tracker camera-emulator, its own process) "
                             "over VISCA on UDP instead of the twin")
    parser.add_argument("--camera-rate-hz", type=float, default=25.0, help="the camera's command rate")
    parser.add_argument("--nice", type=int, default=0, help="run the service this much nicer (<0: less nice)")
    parser.add_argument("--seconds", type=float, default=20.0, help="longest load phase (s)")
    parser.add_argument("--idle-seconds", type=float, default=5.0)
    parser.add_argument("--viewers", type=int, default=50)
    parser.add_argument("--rest", type=int, default=600, help="REST calls in the burst")
    parser.add_argument("--diagnoses", type=int, default=2, help="uploads + diagnoses, one after the other")
    parser.add_argument("--measurement-s", type=float, default=30.0, help="length of the uploaded log (s)")
    args = parser.parse_args()
    args.viewers, args.rest, args.diagnoses = (
        min(args.viewers, 200),
        min(args.rest, 5000),
        min(args.diagnoses, 5),
    )
    csv = measurement_csv(args.measurement_s)
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "bench_probe.py"
        probe.write_text(PROBE)
        ticks_file = Path(tmp) / "ticks.bin"
        alone_file = Path(tmp) / "alone.bin"
        alone: subprocess.Popen[bytes] | None = None
        env = {
            **os.environ,
            "PYTHONPATH": f"{args.tree}{os.pathsep}{tmp}",
            "BENCH_TICKS": str(ticks_file),
            "TRACKER_DATA_DIR": str(Path(tmp) / "data"),
            "TRACKER_VIEWER_ENABLED": "false",
            "TRACKER_AUDIO_ENABLED": "false",
            "TRACKER_LOG_LEVEL": "warning",
            "TRACKER_CONTROL_CHUNK_MS": f"{args.chunk_ms:g}",
            "TRACKER_CONTROL_LOOP_PRIORITY": str(args.priority),
        }
        if args.spin_ms is not None:
            env["BENCH_SPIN_S"] = str(args.spin_ms / 1e3)
        if args.loop_process:
            env["TRACKER_LOOP_PROCESS"] = "true"
            env["BENCH_PROBE"] = str(probe)
            (Path(tmp) / "sitecustomize.py").write_text(CHILD_PROBE)
        if args.service_priority:  # a tree without the setting would refuse it
            env["TRACKER_SERVICE_THREADS_PRIORITY"] = str(args.service_priority)
        emulator: subprocess.Popen[bytes] | None = None
        if args.camera:
            cam_port = free_port()
            emulator = subprocess.Popen(
                [sys.executable, "-m", "tracker", "camera-emulator", "--port", str(cam_port)],
                env={**env, "PYTHONPATH": args.tree}, cwd=tmp, stdout=subprocess.DEVNULL)
            env["TRACKER_DRIVER"] = f"visca+udp://127.0.0.1:{cam_port}"
            env["TRACKER_CAMERA_RATE_HZ"] = f"{args.camera_rate_hz:g}"
        proc = subprocess.Popen(
            [sys.executable, str(probe), "serve", "--host", "127.0.0.1", "--port", str(port)],
            env=env,
            cwd=tmp,
            stdout=subprocess.DEVNULL,
            preexec_fn=(lambda: os.nice(args.nice)) if args.nice else None,
            start_new_session=True,  # its worker processes go with it if it must be killed
        )
        api = f"http://127.0.0.1:{port}/api/v1"
        loop_pid: int | None = None
        try:
            end = time.monotonic() + 180.0
            while True:
                try:
                    if httpx.get(f"{api}/health", timeout=1.0).status_code == 200:
                        break
                except httpx.HTTPError:
                    pass
                if time.monotonic() > end or proc.poll() is not None:
                    raise SystemExit("the service did not start")
                time.sleep(0.2)
            key = (Path(tmp) / "data" / "admin.key").read_text().strip()
            args.pid = proc.pid
            if args.loop_process:
                st = httpx.get(f"{api}/status", headers={"X-API-Key": key}, timeout=10.0).json()
                loop_pid = int(st["driver"]["loop_process"]["pid"])
                ticks_file = Path(f"{ticks_file}.{loop_pid}")
            if args.alone:
                (Path(tmp) / "alone.py").write_text(ALONE)
                alone = subprocess.Popen(
                    [sys.executable, str(Path(tmp) / "alone.py")],
                    env={**env, "BENCH_TICKS": str(alone_file), "BENCH_PROBE": str(probe),
                         "BENCH_CHUNK_S": str(args.chunk_ms / 1e3), "BENCH_PRIORITY": str(args.priority)},
                    cwd=tmp,
                )
            loop = asyncio.new_event_loop()
            try:
                res = loop.run_until_complete(
                    bench(args, api, f"ws://127.0.0.1:{port}/api/v1/telemetry", key, csv))
            finally:  # a client task stuck in its clean-up must not hold up the figures
                for task in asyncio.all_tasks(loop):
                    task.cancel()
                loop.close()
        finally:
            if loop_pid is not None:  # the loop's process writes its ticks (the service none)
                os.kill(loop_pid, signal.SIGUSR1)
            proc.send_signal(signal.SIGUSR1)  # the probe writes the ticks now: the service may
            end = time.monotonic() + 30.0     # not stop in time with a diagnosis still running
            while not ticks_file.exists() and time.monotonic() < end and proc.poll() is None:
                time.sleep(0.1)
            time.sleep(0.5)  # let it finish writing
            if alone is not None:
                alone.terminate()
                alone.wait(30)
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)
            if emulator is not None:
                emulator.send_signal(signal.SIGINT)
                try:
                    emulator.wait(10)
                except subprocess.TimeoutExpired:
                    emulator.kill()
                    emulator.wait(10)
        ticks, ends, cmds, gcs = read_ticks(ticks_file)
        alone_ticks, alone_ends, _, _ = read_ticks(alone_file)
    period = args.chunk_ms / 1e3
    load_avg = os.getloadavg()
    print(
        f"tree {args.tree}, {'camera' if args.camera else 'twin'}"
        f"{' in its own process' if args.loop_process else ''}, tick {args.chunk_ms:g} ms, "
        f"priority {args.priority}, service threads {args.service_priority}, spin {args.spin_ms} ms, "
        f"nice {args.nice}, "
        f"{args.viewers} viewers, "
        f"{args.rest} REST calls ({res['refused']} refused with 429) "
        f"in {res['rest_s']:.1f} s, {args.diagnoses} x (upload {args.measurement_s:g} s log + diagnose) "
        f"{'done' if res['job_done'] else 'still running at the end'}; load average {load_avg[0]:.1f}"
    )
    if args.web_fifo:
        print(f"  diagnostic: {res.get('boosted')} other service threads put in SCHED_FIFO {args.web_fifo}")
    for line in res["log"]:
        print(f"  {line}")
    for phase in ("idle", "load"):
        t0, t1 = res[phase]
        tf = tick_figures(ticks, ends, t0, t1, period)
        print(f"{phase:5s} control ticks: {json.dumps({k: round(v, 2) for k, v in tf.items()})}")
    if args.alone:
        for phase in ("idle", "load"):
            t0, t1 = res[phase]
            tf = tick_figures(alone_ticks, alone_ends, t0, t1, period)
            print(f"{phase:5s} ticks of the engine alone in a process: "
                  f"{json.dumps({k: round(v, 2) for k, v in tf.items()})}")
    if args.camera:
        for phase in ("idle", "load"):
            t0, t1 = res[phase]
            cf = command_figures(cmds, t0, t1, 1.0 / args.camera_rate_hz)
            print(f"{phase:5s} camera command cycles ({args.camera_rate_hz:g} Hz): "
                  f"{json.dumps({k: round(v, 2) for k, v in cf.items()})}")
    t0, t1 = res["load"]
    sel = ticks[(ticks >= t0) & (ticks <= t1)]
    big = [
        (float(a - t0), 1e3 * float(b - a)) for a, b in zip(sel[:-1], sel[1:], strict=True) if b - a > 0.05
    ]
    print(
        f"load started at {t0:.3f}; gaps over 50 ms at (s after, ms): "
        + ", ".join(f"+{a:.2f} {g:.0f}" for a, g in big[:20])
    )
    gf = gc_figures(gcs, t0, t1)
    print(f"load  garbage collections: {json.dumps({k: round(v, 2) for k, v in gf.items()})}")
    ff = frame_figures(res["viewers"], t0, t1)
    print(f"load  telemetry frames: {json.dumps({k: round(v, 2) for k, v in ff.items()})}")
    if res.get("status_faults"):
        print(f"/status faults: {res['status_faults']}")
    if res["status_loop"] is not None:
        print(f"/status loop (since start): {json.dumps(res['status_loop'])}")
    if args.camera and res["status_driver"] is not None:
        d = {k: res["status_driver"].get(k) for k in ("achieved_rate_hz", "missed_periods", "rtt_ms_p95")}
        print(f"/status driver (since start): {json.dumps(d)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
