"""Workbench benchmark: fit and compare time for 30 s at 1 kHz, parameter recovery, and EMPS figures.

Run: ``.venv/bin/python bench/bench_workbench.py`` (add ``--quick`` to skip the per-effect table).
Times are the median of 3 runs after a warm-up (numba compiles once and caches). On this shared
2-core machine OpenBLAS threads fight each other: ``OPENBLAS_NUM_THREADS=1`` roughly halves the
fit time (the fit's linear algebra is small; threading only adds overhead).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from collections.abc import Callable

from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import compare_model
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.fit.fit import fit_model
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.emps import DEFAULT_DATA_DIR, PUBLISHED_PARAMS, emps_model, load_emps

RECOVERY = {
    "base": {},
    "offset": {"offset.torque": 0.012},
    "gravity": {"gravity.torque": 0.06, "gravity.phase": 0.5},
    "coulomb_asymmetry": {"coulomb_asymmetry.negative": 0.075},
    "viscous_asymmetry": {"viscous_asymmetry.negative": 2.5e-3},
    "stiction": {"stiction.static_torque": 0.085, "stiction.velocity": 0.08},
    "delay": {"delay.seconds": 0.014},
    "saturation": {"saturation.limit": 3.0},
    "ripple": {"ripple.amplitude": 0.012, "ripple.cycles_per_rev": 21.0, "ripple.phase": -0.7},
    "compliance": {"compliance.frequency": 15.0, "compliance.damping": 0.1},
    "backlash": {"backlash.width": 0.01},
}
PERTURBED = {"inertia.J": 1.25, "viscous.b": 0.7, "coulomb.torque": 1.35}


def timed(fn: Callable[[], object], repeats: int = 3) -> float:
    """Median wall time (s) of ``fn`` after one warm-up call."""
    return timed_cpu(fn, repeats)[0]


def timed_cpu(fn: Callable[[], object], repeats: int = 3) -> tuple[float, float]:
    """Median wall and CPU time (s) of ``fn`` after one warm-up call. On a shared machine the
    CPU time is the steadier figure (wall time counts the other processes' turns)."""
    fn()
    walls, cpus = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus)


def load_average() -> str:
    """The 1-minute load average (2 cores here: above 2, timings wait for the CPU)."""
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except OSError:
        return "?"


def start_model(effects: tuple[str, ...]) -> AxisModel:
    pan = AxisModel.for_axis("pan", effects)
    return pan.with_params({k: pan.params[k] * f for k, f in PERTURBED.items()})


def speed(meas: Measurement) -> None:
    base = start_model(("offset",))
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    print(f"== speed: 30 s at 1 kHz, pan + offset, closed loop (OPENBLAS_NUM_THREADS={threads}) ==")
    print(f"(median of 3 after a warm-up, wall and CPU; load average {load_average()} on this machine)")
    timed_line("fit (k-step, default horizon)", lambda: fit_model(meas, base), target=True)
    timed_line("fit (inverse dynamics only)", lambda: fit_model(meas, base, method="inverse_dynamics"))
    timed_line("compare (k-step, with breakdown)", lambda: compare_model(meas, base))
    timed_line("compare (free simulation)", lambda: compare_model(meas, base, mode="free"))
    two_mass_speed()
    diagnose_hook(meas)


def timed_line(label: str, fn: Callable[[], object], target: bool = False) -> None:
    wall, cpu = timed_cpu(fn)
    print(f"{label:<36}{wall:6.3f} s   (CPU {cpu:.3f} s{'; target <= 1 s' if target else ''})")


def two_mass_speed() -> None:
    """Fit time of the two-mass models: 30 s at 1 kHz with a 15 Hz belt (or a 0.01 rad dead
    band), started off."""
    for effect in ("compliance", "backlash"):
        true = AxisModel.for_axis("pan", ("quantization", effect), RECOVERY[effect])
        meas = closed_loop_log(true, duration_s=30.0, seed=11, disturbance_nm=0.0005)
        start = start_model((effect,))
        timed_line(f"fit two-mass (+ {effect})", lambda m=meas, s=start: fit_model(m, s), target=True)


def diagnose_hook(meas: Measurement) -> None:
    """Diagnose time (the diagnosis engineer fills this in)."""
    return None


def recovery() -> None:
    print(
        "\n== parameter recovery: hidden effect, 30 s closed loop, 0.5 mN·m disturbance, start 25-40 % off =="
    )
    print(
        f"{'effect':<18} {'time s':>6} {'fit %':>8} {'inc. fit %':>10}  "
        "worst error of the effect's parameters"
    )
    for effect, params in RECOVERY.items():
        effects = () if effect == "base" else (effect,)
        true = AxisModel.for_axis("pan", ("quantization", *effects), params)
        meas = closed_loop_log(true, duration_s=30.0, seed=11, disturbance_nm=0.0005)
        t0 = time.perf_counter()
        res = fit_model(meas, start_model(effects))
        el = time.perf_counter() - t0
        names = list(params) or ["inertia.J", "viscous.b", "coulomb.torque"]
        errs = []
        for n in names:
            if n.endswith(".phase"):
                errs.append(f"{n} {math.remainder(res.params[n] - true.params[n], 2 * math.pi):+.3f} rad")
            else:
                errs.append(f"{n} {100 * (res.params[n] / true.params[n] - 1):+.1f} %")
        print(
            f"{effect:<18} {el:6.2f} {res.fit_percent:8.3f} {res.fit_percent_increment:10.2f}  "
            + ", ".join(errs)
        )


def stderr_calibration(runs: int = 12) -> None:
    """Are the standard errors honest? RMS of (estimate − truth)/stderr over independent runs ≈ 1."""
    true = AxisModel.for_axis("pan", ("quantization", "offset"), {"offset.torque": 0.01})
    names = ("inertia.J", "viscous.b", "coulomb.torque", "offset.torque")
    z: dict[str, list[float]] = {n: [] for n in names}
    for seed in range(runs):
        meas = closed_loop_log(true, duration_s=30.0, seed=100 + seed, disturbance_nm=0.002)
        res = fit_model(meas, start_model(("offset",)))
        for n in names:
            z[n].append((res.params[n] - true.params[n]) / res.stderr[n])
    print(f"\n== standard errors: {runs} runs, 2 mN·m coloured disturbance; RMS z should be ≈ 1 ==")
    print("  " + ", ".join(f"{n} {math.sqrt(statistics.fmean(v * v for v in z[n])):.2f}" for n in names))


def emps() -> None:
    path = DEFAULT_DATA_DIR / "DATA_EMPS.mat"
    if not path.exists():
        print(f"\n(EMPS data not found at {path})")
        return
    meas, gain = load_emps(path)
    print(f"\n== EMPS (DATA_EMPS.mat, {meas.n} samples, gtau = {gain:.4g} N/V), base + offset ==")
    pub = AxisModel.create(gain, PUBLISHED_PARAMS, ("offset",))
    start = emps_model(("offset",), gain)
    before = compare_model(meas, start)
    print(
        f"catalogue defaults (before fit): fit {before.fit_percent:8.3f} %  "
        f"increment fit {before.fit_percent_increment:8.2f} %"
    )
    c = compare_model(meas, pub)
    print(
        f"published parameters:            fit {c.fit_percent:8.3f} %  "
        f"increment fit {c.fit_percent_increment:8.2f} %"
    )
    print(f"{'':<26}" + "".join(f"{n:>22}" for n in PUBLISHED_PARAMS))
    print(f"{'published':<26}" + "".join(f"{v:22.4f}" for v in PUBLISHED_PARAMS.values()))
    for label, kwargs in (
        ("inverse dynamics", {"method": "inverse_dynamics"}),
        ("k-step 30 ms (default)", {}),
        ("k-step 10 ms", {"horizon_s": 0.01}),
        ("k-step 50 ms", {"horizon_s": 0.05}),
        ("k-step 100 ms", {"horizon_s": 0.1}),
    ):
        res = fit_model(meas, start, **kwargs)  # type: ignore[arg-type]
        row = "".join(
            f"{res.params[n]:10.4f} ({100 * (res.params[n] / v - 1):+5.2f}%)"
            for n, v in PUBLISHED_PARAMS.items()
        )
        print(f"{label:<26}{row}   fit {res.fit_percent:.3f} % / inc {res.fit_percent_increment:.2f} %")
        if not kwargs:
            se = ", ".join(f"{n} ± {res.stderr[n]:.3g}" for n in PUBLISHED_PARAMS)
            print(
                f"{'':<26}stderr: {se}; relative force error of the ID step "
                f"{res.inverse_dynamics_error_percent:.2f} %"
            )
    print("the loop (every version refitted, k-step 30 ms):")
    fitted = {}
    for effects in (
        (),
        ("offset",),
        ("offset", "viscous_asymmetry"),
        ("viscous_asymmetry",),
        ("offset", "coulomb_asymmetry"),
    ):
        res = fit_model(meas, emps_model(effects, gain))
        fitted[effects] = res.model
        vals = ", ".join(f"{k} {res.params[k]:.4g}" for k in res.free)
        label = "base" + "".join(f" + {e}" for e in effects)
        print(f"  {label:<34} fit {res.fit_percent:.3f} % / inc {res.fit_percent_increment:.2f} %: {vals}")
        for w in res.warnings[:1]:
            print(f"  {'':<34} warning: {w}")
    pulses = DEFAULT_DATA_DIR / "DATA_EMPS_PULSES.mat"
    if pulses.exists():
        val, _ = load_emps(pulses)
        print("validation on DATA_EMPS_PULSES (models fitted on DATA_EMPS; force pulses unmodelled):")
        for label, model in (("published", pub), *((" + ".join(("base", *e)), m) for e, m in fitted.items())):
            c = compare_model(val, model)
            print(f"  {label:<34} fit {c.fit_percent:.3f} % / inc {c.fit_percent_increment:.2f} %")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="skip the parameter-recovery table")
    args = ap.parse_args(argv)
    base = AxisModel.for_axis("pan", ("quantization", "offset"), {"offset.torque": 0.01})
    speed(closed_loop_log(base, duration_s=30.0, seed=1, disturbance_nm=0.001))
    if not args.quick:
        recovery()
        stderr_calibration()
    emps()
    return 0


if __name__ == "__main__":
    sys.exit(main())
