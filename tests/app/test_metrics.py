"""Issue #11 item 7: /metrics in the Prometheus text format (parsed with prometheus_client's own
parser), its key, and counters that move with what the service does."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families

from .conftest import Rig, make_rig, poll

API = "/api/v1"


@pytest.fixture(scope="module")
def mrig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    yield from make_rig(tmp_path_factory.mktemp("metrics"))


def scrape(rig: Rig, role: str = "viewer") -> dict[str, Any]:
    """name -> {labels tuple -> value}, every sample of one scrape."""
    r = rig.client.get("/metrics", headers=rig.h(role))
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/plain; version=0.0.4")
    samples: dict[str, Any] = {}
    for family in text_string_to_metric_families(r.text):
        for s in family.samples:
            samples.setdefault(s.name, {})[tuple(sorted(s.labels.items()))] = s.value
    return samples


def value(samples: dict[str, Any], name: str, **labels: str) -> float:
    return float(samples.get(name, {}).get(tuple(sorted(labels.items())), 0.0))


def test_metrics_need_a_viewer_key_by_default_header_or_bearer(mrig: Rig) -> None:
    assert mrig.client.get("/metrics").status_code == 401
    assert mrig.client.get("/metrics", headers={"X-API-Key": "3dat_wrong"}).status_code == 401
    r = mrig.client.get("/metrics", headers={"Authorization": f"Bearer {mrig.keys['viewer']}"})
    assert r.status_code == 200 and "tracker_control_ticks_total" in r.text


def test_the_control_loop_is_visible_ticks_gaps_and_lateness(mrig: Rig) -> None:
    # past the start (the loop's first ticks wait a few hundred ms for the workers' start)
    assert poll(lambda: value(scrape(mrig), "tracker_control_ticks_total") >= 30, 10.0)
    first = scrape(mrig)
    time.sleep(0.3)
    second = scrape(mrig)
    ticks = value(second, "tracker_control_ticks_total")
    assert ticks - value(first, "tracker_control_ticks_total") >= 10  # 100 ticks/s, allow a slow box
    assert value(second, "tracker_engine_running") == 1.0 and value(second, "tracker_drive_faulted") == 0.0
    assert value(second, "tracker_control_period_seconds") == pytest.approx(0.01)
    gaps = value(second, "tracker_control_tick_gap_seconds_count")
    assert ticks - 2 <= gaps <= ticks  # one gap per tick after the first (scraped a moment apart)
    # the gaps span first to last tick: no less than the grid's periods (more after a restart)
    # (catch-up ticks after an overrun come closer than a period: a loaded machine shows it)
    assert value(second, "tracker_control_tick_gap_seconds_sum") >= 0.5 * (gaps - 1) * 0.01
    inf = value(second, "tracker_control_tick_gap_seconds_bucket", le="+Inf")
    on_time = value(second, "tracker_control_tick_gap_seconds_bucket", le="0.011")
    assert inf == gaps and on_time >= 0.5 * gaps  # most ticks come one period apart
    assert 0.0 <= value(second, "tracker_control_last_tick_age_seconds") < 1.0
    for name in ("tracker_control_overruns_total", "tracker_control_restarts_total",
                 "tracker_control_lateness_max_seconds", "tracker_control_lateness_mean_seconds"):
        assert name in second


def test_http_requests_are_counted_by_route_template_not_raw_url(mrig: Rig) -> None:
    before = scrape(mrig)
    for _ in range(3):
        assert mrig.client.get(f"{API}/status", headers=mrig.h("viewer")).status_code == 200
    for axis in ("pan", "tilt", "roll"):
        mrig.client.get(f"{API}/axes/{axis}/gains")  # no key: refused by the guard
    mrig.client.get(f"{API}/no/such/{time.time()}")
    after = scrape(mrig)
    route = "/api/v1/status"
    assert value(after, "tracker_http_requests_total", method="GET", route=route, status="200") - value(
        before, "tracker_http_requests_total", method="GET", route=route, status="200") == 3
    assert value(after, "tracker_http_request_duration_seconds_count", method="GET", route=route) - value(
        before, "tracker_http_request_duration_seconds_count", method="GET", route=route) == 3
    gains = "/api/v1/axes/{axis}/gains"
    assert value(after, "tracker_http_requests_total", method="GET", route=gains, status="401") - value(
        before, "tracker_http_requests_total", method="GET", route=gains, status="401") == 3
    assert value(after, "tracker_http_requests_total", method="GET", route="<unmatched>", status="404") >= 1
    routes = {dict(k)["route"] for k in after["tracker_http_requests_total"]}
    assert not any("roll" in r or "no/such" in r for r in routes), routes


def test_telemetry_viewers_and_frames(mrig: Rig) -> None:
    with mrig.client.websocket_connect(f"{API}/telemetry", headers=mrig.h("viewer")) as ws:
        assert ws.receive_json()["type"] == "hello"
        for _ in range(5):
            assert ws.receive_json()["type"] == "frame"
        during = scrape(mrig)
        assert value(during, "tracker_telemetry_viewers") == 1.0
    assert poll(lambda: value(scrape(mrig), "tracker_telemetry_viewers") == 0.0, 5.0)
    after = scrape(mrig)
    assert value(after, "tracker_telemetry_frames_total") >= 5
    assert value(after, "tracker_telemetry_rate_hz") == pytest.approx(100.0)


def test_jobs_and_heavy_work_are_counted_by_kind_and_outcome(mrig: Rig) -> None:
    r = mrig.client.post(f"{API}/jobs/friction-id", headers=mrig.h("engineer"), json={"axis": "tilt"})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    assert mrig.client.post(f"{API}/jobs/{job_id}/cancel", headers=mrig.h("engineer")).status_code == 200
    assert poll(lambda: value(scrape(mrig), "tracker_jobs_total", kind="friction-id", outcome="cancelled")
                == 1.0, 30.0)
    assert value(scrape(mrig), "tracker_job_duration_seconds_count", kind="friction-id",
                 outcome="cancelled") == 1.0
    before = value(scrape(mrig), "tracker_work_total", kind="gain_preview", outcome="ok")
    r = mrig.client.post(f"{API}/axes/pan/gains/preview", headers=mrig.h("viewer"),
                         json={"gains": {}, "amplitude_deg": 10, "duration_s": 1.0})  # heavy work
    assert r.status_code == 200, r.text
    work = scrape(mrig)
    assert value(work, "tracker_work_total", kind="gain_preview", outcome="ok") == before + 1
    assert value(work, "tracker_work_duration_seconds_count", kind="gain_preview", outcome="ok") == before + 1


def test_metrics_can_be_public_by_setting(tmp_path: Path) -> None:
    for rig in make_rig(tmp_path, metrics_role="public"):
        r = rig.client.get("/metrics")
        assert r.status_code == 200 and "tracker_engine_running 1.0" in r.text
