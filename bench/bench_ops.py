"""Benchmark: what observability costs: the metrics middleware per request, a /metrics scrape,
an audit entry, the tick-gap bookkeeping per control tick, and /status through the whole app.

    .venv/bin/python bench/bench_ops.py

The middleware is timed around a bare ASGI app (so only its own work shows): a request whose
route the guard named, one it has to match itself (a refused or unknown path), against the
bare app. The whole-app figure is GET /api/v1/status through TestClient with and without the
middleware (its share of a real request). On a shared machine: best of 5 runs.
"""

from __future__ import annotations

import asyncio
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from app.audit import AuditLog
from app.auth import Principal, Role
from app.db import Database
from app.guard import ROUTE_KEY
from app.metrics import Metrics, MetricsMiddleware
from tracker.realtime import TickStats


def best_us(fn: Any, n: int, runs: int = 5) -> float:  # noqa: ANN401
    """Best of ``runs`` mean microseconds per call of ``fn`` over ``n`` calls."""
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n * 1e6)
    return best


def middleware_figures() -> dict[str, float]:
    async def bare(scope: Any, receive: Any, send: Any) -> None:  # noqa: ANN401
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"{}"})

    from app.main import create_app
    from app.settings import load_settings

    routed_app = create_app(load_settings(None, data_dir=tempfile.mkdtemp(), audio_enabled=False,
                                          viewer_enabled=False))
    routed_app.state.svc = SimpleNamespace(metrics=Metrics())
    wrapped = MetricsMiddleware(bare)
    loop = asyncio.new_event_loop()

    async def receive() -> dict[str, Any]:
        return {"type": "http.request", "body": b""}

    async def send(_: Any) -> None:  # noqa: ANN401
        return None

    def call(app: Any, **extra: Any) -> Any:  # noqa: ANN401
        scope = {"type": "http", "method": "GET", "path": "/api/v1/axes/pan/gains", "app": routed_app,
                 "headers": [], "query_string": b"", "root_path": "", **extra}
        return lambda: loop.run_until_complete(app(scope, receive, send))

    n = 5000
    base = best_us(call(bare), n)
    named = best_us(call(wrapped, **{ROUTE_KEY: "/api/v1/axes/{axis}/gains"}), n)
    matched = best_us(call(wrapped), n)
    unknown = best_us(call(wrapped, path="/no/such/path"), n)
    loop.close()
    return {"bare_us": base, "named_us": named - base, "matched_us": matched - base,
            "unmatched_us": unknown - base}


def app_figures() -> dict[str, float]:
    """GET /api/v1/status through the whole app, with and without the metrics middleware."""
    from fastapi.testclient import TestClient

    import app.main as main_mod
    from app.main import create_app
    from app.settings import load_settings

    out = {}
    for label, middleware in (("with", main_mod.MetricsMiddleware), ("without", None)):
        original = main_mod.MetricsMiddleware
        if middleware is None:
            main_mod.MetricsMiddleware = lambda app: app  # type: ignore[assignment,misc]
        try:
            settings = load_settings(None, data_dir=tempfile.mkdtemp(), audio_enabled=False,
                                     viewer_enabled=False)
            application = create_app(settings)
        finally:
            main_mod.MetricsMiddleware = original  # type: ignore[misc]
        with TestClient(application) as client:
            key = (Path(settings.data_dir) / "admin.key").read_text().strip()
            headers = {"X-API-Key": key}
            for _ in range(50):
                client.get("/api/v1/status", headers=headers)
            out[label] = best_us(lambda c=client, h=headers: c.get("/api/v1/status", headers=h), 300)
            if middleware is not None:
                svc = application.state.svc
                out["scrape_us"] = best_us(svc.metrics.render, 200)
                out["scrape_bytes"] = float(len(svc.metrics.render()))
    return out


def audit_us() -> float:
    with tempfile.TemporaryDirectory() as d:
        log = AuditLog(Database(Path(d) / "a.sqlite3"), coalesce_s=0.0)
        who = Principal(1, "bench", Role.operator)
        i = iter(range(10**9))
        return best_us(lambda: asyncio.run(log.record(who, "pointing.set", "", {"pan_deg": next(i)})), 300)


def tick_us() -> float:
    stats = TickStats(0.01)
    t = iter(range(10**9))
    with_gap = best_us(lambda: stats.record(1e-5, next(t) * 0.01), 200_000)
    plain = TickStats(0.01)
    without = best_us(lambda: plain.record(1e-5), 200_000)
    return with_gap - without


def main() -> None:
    mw = middleware_figures()
    print("metrics middleware, its own cost per request (bare ASGI app: "
          f"{mw['bare_us']:.1f} µs):")
    print(f"  route named by the request guard   {mw['named_us']:6.1f} µs")
    print(f"  route matched by the middleware    {mw['matched_us']:6.1f} µs  (refused before routing)")
    print(f"  no route (404)                     {mw['unmatched_us']:6.1f} µs")
    whole = app_figures()
    print(f"GET /api/v1/status through the app: {whole['with']:.0f} µs with the middleware, "
          f"{whole['without']:.0f} µs without ({whole['with'] - whole['without']:+.0f} µs)")
    print(f"a /metrics scrape: {whole['scrape_us'] / 1e3:.2f} ms, {whole['scrape_bytes'] / 1e3:.1f} kB")
    print(f"an audit entry (one SQLite transaction, WAL): {audit_us():.0f} µs")
    print(f"tick-gap bookkeeping per control tick: {tick_us():.2f} µs")


if __name__ == "__main__":
    main()
