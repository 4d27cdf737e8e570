"""Diagnosis benchmark: speed (30 s at 1 kHz, every candidate) and the hidden-effect scorecard.

    .venv/bin/python bench/bench_diagnose.py [--seeds N] [--duration S]

For each effect of the catalogue, N rigs with that effect hidden at random physical parameters
(tracker.workbench.experiments.experiments.HIDDEN_RANGES) record a closed-loop run; the base model is
diagnosed. Printed per effect: verdict rate, median and worst parameter error, fit % before →
after adding the candidate. Plus the clean case (no verdict wanted) and pairs (both effects
found one after the other, adding the verdict's refitted model between diagnoses), and the
EMPS loop (real data) when the data is present.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import diagnose
from tracker.workbench.experiments.experiments import HIDDEN_RANGES, generate_measurement, random_hidden_model

EFFECTS = tuple(HIDDEN_RANGES)
PAIRS = (
    ("gravity", "delay"),
    ("offset", "ripple"),
    ("saturation", "stiction"),
    ("viscous_asymmetry", "compliance"),
    ("backlash", "gravity"),
)
ACCEPT = {"coulomb_asymmetry": ("coulomb_asymmetry", "offset")}  # equivalent on a rigid axis


def param_error(name: str, got: float, want: float) -> float:
    """Relative error in % (absolute error in degrees ×(100/5.7) for phases: 0.1 rad ~ 10 %)."""
    if name.endswith(".phase"):
        d = (got - want + math.pi) % (2 * math.pi) - math.pi
        return 100.0 * abs(d)
    return 100.0 * abs(got - want) / abs(want)


def effect_errors(
    effect: str, verdict: str | None, cand_model: AxisModel | None, true: AxisModel
) -> dict[str, float]:
    if cand_model is None:
        return {}
    p = cand_model.params
    if effect == "coulomb_asymmetry" and verdict == "offset":
        o = p["offset.torque"]
        return {
            "coulomb_asymmetry.negative": param_error(
                "x", p["coulomb.torque"] - o, true.params["coulomb_asymmetry.negative"]
            )
        }
    return {
        k: param_error(k, p[k], v) for k, v in true.params.items() if k.split(".")[0] == effect and k in p
    }


def speed(duration_s: float) -> None:
    times, cpus = [], []
    for effect in ("stiction", "compliance", None):
        true = random_hidden_model("pan", [effect], 1) if effect else AxisModel.for_axis("pan")
        meas = generate_measurement(true, duration_s, seed=1)
        diagnose(meas, AxisModel.for_axis("pan"))  # compile
        for _ in range(3):
            t0, c0 = time.perf_counter(), time.process_time()
            diagnose(meas, AxisModel.for_axis("pan"))
            times.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
    load = f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "?"
    print(
        f"diagnose, {duration_s:g} s at 1 kHz, all {len(EFFECTS)} candidates + quantization: "
        f"median {statistics.median(times):.2f} s, max {max(times):.2f} s over {len(times)} runs "
        f"(CPU median {statistics.median(cpus):.2f} s, max {max(cpus):.2f} s; load {load}; target <= 2 s)"
    )


def scorecard(seeds: int, duration_s: float) -> None:
    print(f"\nhidden-effect scorecard ({seeds} random rigs per effect, {duration_s:g} s closed-loop runs)")
    print(f"{'effect':<18} {'verdict':>8} {'param err % (median / worst)':>32} {'fit % before → after':>24}")
    clean_ok = 0
    for s in range(seeds):
        d = diagnose(
            generate_measurement(AxisModel.for_axis("pan"), duration_s, seed=900 + s),
            AxisModel.for_axis("pan"),
        )
        clean_ok += d.verdict is None
    print(f"{'(clean)':<18} {clean_ok:>3}/{seeds} no verdict")
    for effect in EFFECTS:
        ok, errs, before, after, wrong = 0, [], [], [], []
        for s in range(seeds):
            true = random_hidden_model("pan", [effect], 1000 + 37 * s)
            meas = generate_measurement(true, duration_s, seed=1000 + 37 * s)
            d = diagnose(meas, AxisModel.for_axis("pan"))
            good = d.verdict in ACCEPT.get(effect, (effect,))
            ok += good
            if not good:
                wrong.append(str(d.verdict))
            if good:
                cand = d.candidate(d.verdict)  # type: ignore[arg-type]
                errs.append(effect_errors(effect, d.verdict, cand.model, true))
                before.append(d.fit_percent)
                after.append(cand.fit_percent)
        names = sorted({k for e in errs for k in e})
        txt = ", ".join(
            f"{n.split('.')[1]} {statistics.median(e[n] for e in errs):.1f}/{max(e[n] for e in errs):.1f}"
            for n in names
        )
        fit = f"{statistics.median(before):.3f} → {statistics.median(after):.3f}" if before else "-"
        miss = f"  (missed: {', '.join(wrong)})" if wrong else ""
        print(f"{effect:<18} {ok:>3}/{seeds:<4} {txt:>32} {fit:>24}{miss}")
    print("\npairs (diagnose, add the verdict refitted, diagnose again; then nothing left):")
    for pair in PAIRS:
        hits = 0
        for s in range(seeds):
            true = random_hidden_model("pan", pair, 2000 + 53 * s)
            meas = generate_measurement(true, duration_s, seed=2000 + 53 * s)
            model, found, fits = AxisModel.for_axis("pan"), [], []
            for _ in range(3):
                d = diagnose(meas, model)
                fits.append(d.fit_percent)
                if d.verdict is None:
                    break
                found.append(d.verdict)
                model = d.candidate(d.verdict).model or model
            equiv = {ACCEPT.get(e, (e,))[-1] if e in ACCEPT else e for e in pair}
            got = {
                ("offset" if f in ("offset", "coulomb_asymmetry") and "coulomb_asymmetry" in pair else f)
                for f in found
            }
            hit = got == equiv and len(found) == 2
            hits += hit
            print(
                f"  {'+'.join(pair):<30} seed {s}: found {found or '-'}; "
                f"fit % {' → '.join(f'{f:.3f}' for f in fits)}"
                f"{'' if hit else '  MISS'}"
            )
        print(f"  {'+'.join(pair):<30} {hits}/{seeds} both found")


def emps() -> None:
    try:
        from tracker.workbench.measurements.emps import DEFAULT_DATA_DIR, emps_model, load_emps

        meas, _ = load_emps(DEFAULT_DATA_DIR / "DATA_EMPS.mat")
    except Exception as exc:  # noqa: BLE001 - the data is optional here
        print(f"\nEMPS: skipped ({exc})")
        return
    print("\nEMPS (real data), diagnose from the base model, add the verdict, diagnose again:")
    model = emps_model(())
    for _ in range(3):
        t0 = time.perf_counter()
        d = diagnose(meas, model)
        top = [
            (c.effect, round(c.screen_gain, 2), round(c.kstep_gain, 2)) for c in d.candidates if c.significant
        ]
        print(
            f"  {'+'.join(model.effects) or 'base'}: verdict {d.verdict} ({time.perf_counter() - t0:.2f} s); "
            f"significant (effect, held-out torque gain, k-step gain): {top}"
        )
        if d.verdict is None:
            break
        c = d.candidate(d.verdict)
        print(f"    {c.evidence}")
        model = c.model or model
        shown = {k: v for k, v in model.params.items() if k != "inertia.motor_fraction"}
        print("    → " + ", ".join(f"{k} = {v:.4g}" for k, v in shown.items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--duration", type=float, default=30.0)
    args = ap.parse_args()
    speed(30.0)
    scorecard(args.seeds, args.duration)
    emps()


if __name__ == "__main__":
    main()
