"""Camera workbench scorecard on the independent PTZ log generator (tests/.../ptz_log_generator.py):
which hidden effects the diagnosis names (rounds of diagnose → add the verdict → diagnose), false
alarms on clean logs, and how close the fit gets to the hidden parameters.

    .venv/bin/python bench/bench_camera_workbench.py [N]
"""

from __future__ import annotations

import math
import random
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.tracker.workbench.camera.ptz_log_generator import generate, random_truth, to_csv  # noqa: E402
from tracker.workbench.camera.diagnose import diagnose_camera  # noqa: E402
from tracker.workbench.camera.fit import fit_camera  # noqa: E402
from tracker.workbench.camera.log import parse_camera_log  # noqa: E402
from tracker.workbench.camera.model import CameraModel  # noqa: E402


def verdicts(log, rounds=4):  # type: ignore[no-untyped-def]
    model = CameraModel.base(log.max_step)
    named = []
    for _ in range(rounds):
        d = diagnose_camera(log, model)
        if d.verdict is None:
            break
        named.append(d.verdict)
        model = next(c.model for c in d.candidates if c.effect == d.verdict)
    return named


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    cases = {
        "clean": {},
        "latency+speed_table": {"latency": True, "table": True},
        "acceleration": {"accel": True},
        "backlash": {"backlash": True},
        "latency": {"latency": True},
    }
    expect = {
        "clean": set(),
        "latency+speed_table": {"latency", "speed_table"},
        "acceleration": {"acceleration"},
        "backlash": {"backlash"},
        "latency": {"latency"},
    }
    for name, kw in cases.items():
        ok, times, seen = 0, [], []
        for seed in range(n):
            truth = random_truth(random.Random(1000 + seed), **kw)
            log = parse_camera_log(to_csv(*generate(truth, 45.0, 1000 + seed)))
            t0 = time.perf_counter()
            named = verdicts(log)
            times.append(time.perf_counter() - t0)
            ok += set(named) == expect[name]
            seen.append("+".join(named) or "none")
        print(
            f"{name:<22} {ok}/{n} exact   (median {np.median(times):.1f} s per log)   "
            f"verdicts: {', '.join(seen)}"
        )
    lat_err, acc_err, bl_err, tab_med, tab_p90 = [], [], [], [], []
    for seed in range(n):
        truth = random_truth(random.Random(2000 + seed), latency=True, table=True, accel=True, backlash=True)
        log = parse_camera_log(to_csv(*generate(truth, 60.0, 2000 + seed)))
        model = CameraModel.base(
            log.max_step, ("latency", "speed_table", "acceleration", "backlash", "quantization")
        )
        p = fit_camera(log, model)
        v = p.model.params()
        lat_err.append(abs(v["latency.seconds"] - truth.latency_s) / truth.period_s)
        acc_err.append(abs(math.degrees(v["acceleration.limit"]) / truth.accel_deg_s2 - 1))
        bl_err.append(abs(math.degrees(v["backlash.width"]) / truth.backlash_deg - 1))
        rel = np.concatenate(
            [
                np.degrees(p.model.table_rad_s(d)) / np.array(t) - 1
                for d, t in ((1, truth.table_pos_deg_s), (-1, truth.table_neg_deg_s))
            ]
        )
        tab_med.append(np.median(np.abs(rel)))
        tab_p90.append(np.percentile(np.abs(rel), 90))
    print(
        f"fit, all four hidden, {n} logs of 60 s: latency error median {np.median(lat_err):.3f} / worst "
        f"{max(lat_err):.3f} command periods; acceleration {100 * np.median(acc_err):.1f} / "
        f"{100 * max(acc_err):.1f} %; backlash {100 * np.median(bl_err):.1f} / {100 * max(bl_err):.1f} %; "
        f"table |error| median {100 * np.median(tab_med):.2f} %, 90th percentile per log worst "
        f"{100 * max(tab_p90):.1f} %"
    )


if __name__ == "__main__":
    main()
