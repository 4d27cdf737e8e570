"""Is the service healthy? The control loop ticks (within ``health_stall_s``) and the drive has no
latched fault; ``GET /health`` answers 503 with the reasons when not."""

from __future__ import annotations

import math
import time
from typing import Any


def health_of(svc: Any) -> tuple[bool, dict[str, Any]]:  # noqa: ANN401 - the Service
    """(healthy, the JSON body): ``reasons`` says what is wrong, empty when healthy."""
    threshold_s = svc.settings.health_stall_s
    reasons: list[str] = []
    timing = None
    if not svc.engine_running:
        reasons.append("the engine loop is not running")
    else:
        timing = svc.engine.timing()
        if timing.in_thread and timing.running:
            age = timing.last_tick_age_s
            if math.isinf(age):  # no tick yet: count from the loop's start
                age = time.perf_counter() - svc.engine_started_s
            if age > threshold_s:
                reasons.append(f"control loop stalled: no tick for {age:.1f} s "
                               f"(threshold {threshold_s:g} s, setting health_stall_s)")
    faults = list(svc.engine.driver.faults()) if svc.engine is not None else []
    if faults:
        reasons.append(f"drive fault latched: {'; '.join(faults)}")
    body: dict[str, Any] = {
        "ok": not reasons,
        "engine_running": svc.engine_running,
        "reasons": reasons,
        "faults": faults,
        "last_tick_age_s": None if timing is None or math.isinf(timing.last_tick_age_s)
        else round(timing.last_tick_age_s, 4),
        "stall_threshold_s": threshold_s,
    }
    if reasons:
        body |= {"detail": "; ".join(reasons), "error": "Unhealthy"}
    return not reasons, body
