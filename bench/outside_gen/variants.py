"""Why did the workbench say that? Regenerate one log of the matrix with one thing changed, run
the CLI on it, and print the verdict next to the original's.

    python bench/outside_gen/variants.py --out OUT_DIR \
        --name clean-011 --seed 100011 [--effect E] --change tanh,no_inductance,fine_encoder

Changes: tanh (a tanh friction law in place of LuGre),
no_inductance (electrical time constant 10 µs), fine_encoder (16384 counts per motor rev),
no_latency, no_dither, no_stribeck (static level = Coulomb), no_disturbance,
weak_emf (back-EMF damping ×0.09 at the same K), pid (a PI-D loop in place of the
closed loop's controller), light_clip (a saturation log's rail ×2, after the effect is drawn).
Each variant keeps the seed: the same reference, gains and disturbance draw.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bench.outside_gen.generate import truth_of  # noqa: E402
from bench.outside_gen.loop import Encoder, write_csv  # noqa: E402
from bench.outside_gen.scenario import Scenario, draw_base, simulate, with_effect, with_saturation  # noqa: E402
from bench.outside_gen.score import _diagnose_one, verdict_of  # noqa: E402


def changed(sc: Scenario, change: str) -> Scenario:
    pl = sc.plant
    if change == "light_clip":  # applied after the effect: the amplifier's rail twice as high
        m = pl.motor
        return replace(sc, plant=replace(pl, motor=replace(m, amp_rail_v=2 * m.amp_rail_v)))
    if change == "pid":  # the same reference through a PI-D loop (bandwidth 25 rad/s)
        return replace(sc, controller="pid_dom", bandwidth_rad_s=25.0)
    if change == "tanh":
        return replace(sc, plant=replace(pl, law="tanh"))
    if change == "no_inductance":
        return replace(sc, plant=replace(pl, motor=replace(pl.motor, l_h=10e-6 * pl.motor.r_ohm)))
    if change == "fine_encoder":
        return replace(sc, encoder=Encoder(16384, on_motor=True, rounding=sc.encoder.rounding))
    if change == "no_latency":
        return replace(sc, latency_ticks=0)
    if change == "no_dither":
        return replace(sc, dither_v=0.0)
    if change == "no_stribeck":
        sc = replace(sc, plant=replace(pl, friction_motor=replace(pl.friction_motor, fs_nm=0.0)))
        return replace(sc, plant=replace(sc.plant, friction_load=replace(pl.friction_load, fs_nm=0.0)))
    if change == "weak_emf":  # Kt ×0.3, amplifier gain ×1/0.3: the same K, back-EMF damping ×0.09
        m = pl.motor
        weak = replace(m, kt_nm_per_a=0.3 * m.kt_nm_per_a, amp_gain_v_per_v=m.amp_gain_v_per_v / 0.3)
        return replace(sc, plant=replace(pl, motor=weak))
    if change == "no_disturbance":
        return replace(sc, disturbance_nm=1e-9)
    raise SystemExit(f"error: unknown change {change!r}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--effect", default=None)
    ap.add_argument("--change", required=True, help="comma-separated; each alone, then all together")
    ap.add_argument("--tracker-dir", default=str(Path(__file__).resolve().parents[2]))
    a = ap.parse_args()
    changes = a.change.split(",")
    sets = [[c] for c in changes] + ([changes] if len(changes) > 1 else [])
    for group in sets:
        sc = draw_base(a.name, a.seed, a.effect)
        rng = np.random.default_rng(a.seed + 31337)
        for c in group:
            sc = sc if c == "light_clip" else changed(sc, c)
        if a.effect == "saturation":
            sc = with_saturation(sc, simulate(sc), rng)
        elif a.effect:
            sc = with_effect(sc, rng)
        if "light_clip" in group:
            sc = changed(sc, "light_clip")
        name = f"{a.name}~{'+'.join(group)}"
        run = simulate(sc)
        write_csv(str(a.out / f"{name}.csv"), run)
        (a.out / f"{name}.truth.json").write_text(json.dumps(truth_of(sc, run), default=float))
        _diagnose_one((str(a.out), name, a.tracker_dir))
        d = json.loads((a.out / f"{name}.diag.json").read_text())
        v = verdict_of(d)
        cand = next((c for c in d.get("candidates", []) if c["effect"] == v), {})
        print(f"{name}: verdict {v} {cand.get('params')} notes={len(d.get('notes', []))}", flush=True)


if __name__ == "__main__":
    main()
