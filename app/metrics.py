"""Prometheus metrics of the service: ``GET /metrics`` (text format 0.0.4), from prometheus-client.

Each :class:`Metrics` has its own registry (several apps in one process, as in the tests, do
not mix). Two kinds of figures:

- counted as things happen: HTTP requests and their latency by method and *route template*
  (``/api/v1/axes/{axis}/gains``, never the raw URL, so the series stay few; a path no route
  matches is ``<unmatched>``), by :class:`MetricsMiddleware`; jobs (friction-ID) and heavy
  work (workbench, previews) by kind and outcome, with durations.
- read at each scrape from the running service (:class:`ServiceCollector`): the control
  loop's ticks, overruns, restarts, lateness, tick-gap histogram and the age of its latest tick
  (tracker/realtime.py, kept by the loop's own thread: nothing is added to a tick), the
  drive's faults, telemetry viewers and frames sent and dropped, the audio stream's CPU and
  dropped blocks, heavy work in flight, settings not restored.

All names start with ``tracker_``; docs/operations.md lists them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

from prometheus_client import CollectorRegistry, Counter, Histogram, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily, Metric
from prometheus_client.registry import Collector
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.guard import ROUTE_KEY, UNMATCHED

CONTENT_TYPE = "text/plain; version=0.0.4; charset=utf-8"
HTTP_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)
JOB_BUCKETS_S = (0.1, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0)


class Metrics:
    """The registry and the metrics counted as things happen (see the module docstring)."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry(auto_describe=False)  # the service is read only at scrapes
        r = self.registry
        self.http_requests = Counter(
            "tracker_http_requests", "HTTP requests answered, by method, route template and status",
            ["method", "route", "status"], registry=r)
        self.http_latency = Histogram(
            "tracker_http_request_duration_seconds",
            "time from a request's arrival to the end of its response, by method and route template",
            ["method", "route"], buckets=HTTP_BUCKETS_S, registry=r)
        self.jobs = Counter("tracker_jobs", "jobs finished, by kind and outcome (done, failed, cancelled)",
                            ["kind", "outcome"], registry=r)
        self.job_duration = Histogram("tracker_job_duration_seconds", "job run time, by kind and outcome",
                                      ["kind", "outcome"], buckets=JOB_BUCKETS_S, registry=r)
        self.work = Counter("tracker_work", "heavy requests run in the worker pool, by kind and outcome "
                            "(ok, error, lost: the worker died)", ["kind", "outcome"], registry=r)
        self.work_duration = Histogram("tracker_work_duration_seconds",
                                       "heavy work time (queue wait included), by kind and outcome",
                                       ["kind", "outcome"], buckets=HTTP_BUCKETS_S + (30.0, 60.0), registry=r)

    def job_finished(self, kind: str, outcome: str, duration_s: float) -> None:
        self.jobs.labels(kind, outcome).inc()
        self.job_duration.labels(kind, outcome).observe(duration_s)

    def work_finished(self, kind: str, outcome: str, duration_s: float) -> None:
        self.work.labels(kind, outcome).inc()
        self.work_duration.labels(kind, outcome).observe(duration_s)

    def watch(self, svc: Any) -> None:  # noqa: ANN401 - the Service
        """Read ``svc``'s state at every scrape from now on."""
        self.registry.register(ServiceCollector(svc))

    def render(self) -> bytes:
        """The text exposition of every metric."""
        return generate_latest(self.registry)


def route_template(scope: Scope) -> str:
    """The path template of the route ``scope`` reached (or would reach), else ``UNMATCHED``."""
    found = scope.get(ROUTE_KEY)  # an API route, found by the request guard
    if isinstance(found, str):
        return found
    route = scope.get("route")
    path = getattr(route, "path", None)
    if isinstance(path, str):
        return path
    app = scope.get("app")
    probe = {**scope, "path_params": {}}
    for candidate in getattr(getattr(app, "router", None), "routes", ()):
        # A request the guard refused (401, 413) never reached the router: match it here.
        match, _ = candidate.matches(probe)
        if match != Match.NONE:
            return str(getattr(candidate, "path", UNMATCHED)) or UNMATCHED
    return UNMATCHED


class MetricsMiddleware:
    """ASGI middleware: counts every HTTP request and times it, by method and route template."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        svc = getattr(scope["app"].state, "svc", None) if "app" in scope else None
        if scope["type"] != "http" or svc is None:
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        status = 500

        async def send_noting_status(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, send_noting_status)
        finally:
            metrics: Metrics = svc.metrics
            route, method = route_template(scope), str(scope.get("method", ""))
            metrics.http_latency.labels(method, route).observe(time.perf_counter() - t0)
            metrics.http_requests.labels(method, route, str(status)).inc()


class ServiceCollector(Collector):
    """The running service's state, read at each scrape (see the module docstring)."""

    def __init__(self, svc: Any) -> None:  # noqa: ANN401 - the Service
        self.svc = svc

    def collect(self) -> Iterator[Metric]:
        svc = self.svc
        engine = svc.engine
        yield _gauge("tracker_engine_running", "1 while the engine's loop runs", float(svc.engine_running))
        if engine is not None:
            faults = engine.driver.faults()
            yield _gauge("tracker_drive_faulted", "1 while the drive has a latched fault",
                         float(bool(faults)))
            timing = getattr(engine, "timing", None)
            if timing is not None:
                yield from _loop_metrics(timing())
        hub = svc.hub
        yield _gauge("tracker_telemetry_viewers", "telemetry WebSocket clients connected", hub.clients)
        yield _counter("tracker_telemetry_frames", "telemetry frames encoded and fanned out "
                       "(rate(): the frame rate)", hub.frames_sent)
        yield _counter("tracker_telemetry_frames_dropped", "frames dropped for slow telemetry clients "
                       "(their queue was full)", getattr(hub, "frames_dropped", 0))
        yield _gauge("tracker_telemetry_rate_hz", "the configured telemetry frame rate", hub.period_s ** -1)
        audio = svc.audio
        if audio is not None:
            cpu = getattr(audio, "cpu_ms_per_s", float("nan"))
            yield _gauge("tracker_audio_cpu_ratio", "the localizer's CPU time per second of audio "
                         "(1 = a whole core; NaN before the first audio)", cpu / 1000.0)
            yield _counter("tracker_audio_dropped_blocks", "audio blocks the input lost (sound-card "
                           "overflows: the localizer fell behind)", getattr(audio, "dropped_blocks", 0))
        yield _gauge("tracker_work_in_flight", "heavy requests running or waiting", svc.work.admitted)
        yield _gauge("tracker_settings_not_restored", "stored settings refused at start-up (in status)",
                     len(svc.console.warnings))


def _loop_metrics(t: Any) -> Iterator[Metric]:  # noqa: ANN401 - a LoopTiming
    yield _gauge("tracker_control_period_seconds", "the control loop's tick period", t.period_s)
    yield _counter("tracker_control_ticks", "control ticks run", t.ticks)
    yield _counter("tracker_control_overruns", "ticks that started a period or more late", t.overruns)
    yield _counter("tracker_control_restarts", "times the loop fell over 0.1 s behind and started afresh",
                   t.restarts)
    yield _gauge("tracker_control_lateness_last_seconds", "the latest tick's lateness", t.last_lateness_s)
    yield _gauge("tracker_control_lateness_max_seconds", "the largest tick lateness since the warm-up",
                 t.max_lateness_s)
    yield _gauge("tracker_control_lateness_mean_seconds", "the mean tick lateness since the warm-up",
                 t.mean_lateness_s)
    age = getattr(t, "last_tick_age_s", float("inf"))
    yield _gauge("tracker_control_last_tick_age_seconds", "time since the latest tick started "
                 "(+Inf before the first; grows while the loop is stalled)", age)
    bounds, counts = getattr(t, "gap_bounds_s", ()), getattr(t, "gap_counts", ())
    if bounds and counts:
        hist = HistogramMetricFamily("tracker_control_tick_gap_seconds",
                                     "time between the starts of consecutive ticks (one period when on time)")
        cumulative, buckets = 0, []
        for bound, count in zip(bounds, counts, strict=False):
            cumulative += count
            buckets.append((repr(round(bound, 9)), float(cumulative)))
        buckets.append(("+Inf", float(sum(counts))))
        hist.add_metric([], buckets, sum_value=float(t.gap_sum_s))
        yield hist


def _gauge(name: str, doc: str, value: float) -> GaugeMetricFamily:
    return GaugeMetricFamily(name, doc, value=float(value))


def _counter(name: str, doc: str, value: float) -> CounterMetricFamily:
    return CounterMetricFamily(name, doc, value=float(value))
