"""How often the residual test (compare/consistency.py) passes a right model and flags a wrong one.

On the first N clean logs of the truthgen dev split (tests/truthgen: its own physics, friction laws
and controllers), the right model is the true structure fitted; the wrong one the same structure
with Coulomb friction at half its fitted value (J and b refitted around it). Prints one line per
log (true and estimated load disturbance and noise, the ratios to the floor) and the pass rates.

    .venv/bin/python bench/bench_residual_test.py [--n 24] [--replicas 5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.truthgen.matrix import build_matrix, generate_case  # noqa: E402
from tracker.plant.model import AxisModel  # noqa: E402
from tracker.workbench.compare.compare import compare_model  # noqa: E402
from tracker.workbench.fit.fit import fit_model  # noqa: E402
from tracker.workbench.measurements.data import Measurement  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--replicas", type=int, default=5)
    args = ap.parse_args()
    ids = [c.id for c in build_matrix() if c.split == "dev" and c.group == "clean"][: args.n]
    right_ok = wrong_flagged = 0
    for cid in ids:
        log, truth = generate_case(cid)
        meas = Measurement(log.t, log.u, log.theta, cid)
        gain = float(truth["gain_nm_per_v"])
        model = AxisModel.for_axis(str(truth["axis"]), (), gain_nm_per_v=gain)
        right = fit_model(meas, model).model
        v = compare_model(meas, right, replicas=args.replicas).verdict
        fc = right.params["coulomb.torque"]
        start = AxisModel.for_axis(str(truth["axis"]), (), {"coulomb.torque": 0.5 * fc}, gain_nm_per_v=gain)
        wrong = fit_model(meas, start, free=["inertia.J", "viscous.b"]).model
        w = compare_model(meas, wrong, replicas=args.replicas).verdict
        assert v is not None and w is not None
        right_ok += v.consistent
        wrong_flagged += not w.consistent
        noise = truth["noise"]
        print(
            f"{cid:<10} {truth['friction_law']:<8} dist true {noise['disturbance_rms_nm']:.4f} "
            f"est {v.floor.disturbance_rms_nm:.4f} N·m | noise true {noise['theta_std_rad']:.2e} "
            f"est {v.floor.sensor.white_noise_rad:.2e} rad | right {v.rms_rad.ratio:.2f}× "
            f"{'ok' if v.consistent else 'FAIL ' + ','.join(v.failing_regimes) or 'rms'} | "
            f"half Coulomb {w.rms_rad.ratio:.2f}× {'flagged' if not w.consistent else 'MISSED'}",
            flush=True,
        )
    n = len(ids)
    print(
        f"right model consistent: {right_ok}/{n} ({100 * right_ok / n:.0f} %); "
        f"Coulomb at half flagged: {wrong_flagged}/{n} ({100 * wrong_flagged / n:.0f} %)"
    )


if __name__ == "__main__":
    main()
