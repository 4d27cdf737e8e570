"""Benchmark: the seed's lead vs our controller, margins and pointing figures on the twin.

Prints, per axis and controller, the python-control margins of the linearised discrete loop
and the ``tracker simulate`` figures (Coulomb friction, quantized encoder), plus the wall time
of one simulated hour of the closed-loop pointing script. Run:
``.venv/bin/python bench/bench_control.py``.
"""

from __future__ import annotations

from tracker.control.pointing import SCRIPT_S
from tracker.control.scorecard import run_pointing

KEYS = (
    "phase_margin_deg",
    "phase_margin_with_1_sample_delay_deg",
    "gain_margin_db",
    "crossover_hz",
    "rise_time_s",
    "overshoot_percent",
    "settling_time_s",
    "sine_1hz_peak_error_percent",
    "ramp_peak_error_deg",
    "command_variation_v_per_s",
)


def main() -> None:
    for axis in ("pan", "tilt"):
        seed = run_pointing(axis, controller="seed_lead").figures
        ours = run_pointing(axis).figures
        print(f"{axis}: {'':36s} {'seed_lead':>12s} {'observer_pd_ff':>15s}")
        for k in KEYS:
            print(f"  {k:36s} {seed[k]:12.3f} {ours[k]:15.3f}")
        hour = run_pointing(axis, duration_s=3600.0 // SCRIPT_S * SCRIPT_S).figures
        print(f"  one simulated hour of the closed-loop script: {hour['wall_s']:.2f} s wall")


if __name__ == "__main__":
    main()
