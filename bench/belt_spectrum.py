"""Does a belt resonance show as a peak of the rigid model's residual spectrum? (issue 9, item 6)

The idea to speed up the belt search: take the frequency candidates from the residual spectrum
(a few peaks) instead of the 68-point grid of k-step prediction costs. This probe measures, on
the independent generator's compliance logs, where the peaks of the rigid inverse-dynamics
residual torque's Welch spectrum lie (each peak judged against the median of the log spectrum
over ±2× its frequency, z in units of the estimate's own scatter, 1/√segments), and whether
one of the strongest few is within 10 % of the true belt frequency. It also tries the command →
acceleration transfer (H1 = S_ua/S_uu), which in a closed loop estimates −1/C wherever the
command is mostly fed-back encoder noise.

Run: ``.venv/bin/python bench/belt_spectrum.py DIR [DIR ...]`` (folders of ``*compliance*.csv``
with the truth in ``.json`` beside each; dev splits only).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from tracker.plant.model import AxisModel
from tracker.workbench.fit.torques import fit_inverse_dynamics, replace_params, residual_torque_nm
from tracker.workbench.measurements.data import Measurement, read_log
from tracker.workbench.measurements.states import estimate_states

FloatArray = NDArray[np.float64]
TOP = 3


def spectral_peaks(
    f: FloatArray, psd: FloatArray, n_segments: float, f_max: float
) -> list[tuple[float, float]]:
    """(z, frequency) of the local maxima of log ``psd`` above 1 Hz, strongest first: z is the
    excess over the median of log psd at f/2..2f (outside ±30 %) in units of 1/√segments."""
    lp = np.log(np.maximum(psd, 1e-300))
    sig = 1.0 / math.sqrt(max(n_segments, 1.0))
    out = []
    for i in range(1, f.size - 1):
        if not 1.0 <= f[i] <= f_max or lp[i] < lp[i - 1] or lp[i] < lp[i + 1]:
            continue
        near = (
            (f >= f[i] / 2) & (f <= 2 * f[i]) & (np.abs(np.log(np.maximum(f, 1e-9) / f[i])) > math.log(1.3))
        )
        if near.sum() >= 3:
            out.append(((lp[i] - float(np.median(lp[near]))) / sig, float(f[i])))
    return sorted(out, reverse=True)


def welch_segments(n: int) -> int:
    return int(2 ** math.floor(math.log2(max(256, 2 * n / 17))))


def residual_peaks(meas: Measurement, model: AxisModel) -> list[tuple[float, float]]:
    est = estimate_states(meas)
    idf = fit_inverse_dynamics(meas, est, model, ["inertia.J", "viscous.b", "coulomb.torque"])
    r = residual_torque_nm(meas, est, replace_params(model, idf.params))
    fs, nper = 1.0 / meas.dt_s, welch_segments(r.size)
    f, p = signal.welch(r - r.mean(), fs=fs, nperseg=nper)
    return spectral_peaks(f, p, 2 * r.size / nper - 1, 0.4 * fs)


def transfer_peaks(meas: Measurement) -> list[tuple[float, float]]:
    th, fs = meas.theta_rad, 1.0 / meas.dt_s
    a = (th[2:] - 2 * th[1:-1] + th[:-2]) * fs * fs
    u = meas.u_v[:-2]
    nper = welch_segments(u.size)
    f, puu = signal.welch(u, fs=fs, nperseg=nper)
    _, pua = signal.csd(u, a, fs=fs, nperseg=nper)
    return spectral_peaks(f, np.abs(pua / puu) ** 2, 2 * u.size / nper - 1, 0.4 * fs)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("dirs", nargs="+")
    args = ap.parse_args(argv)
    hits = {"residual": 0, "transfer": 0}
    total = 0
    for d in args.dirs:
        for csv in sorted(Path(d).glob("*compliance*.csv")):
            truth = json.loads(csv.with_suffix(".json").read_text())
            f_true = truth["params"]["compliance.frequency"]
            base = AxisModel.for_axis(truth["axis"], ())
            model = AxisModel.create(truth["gain_nm_per_v"], base.params, ())
            meas = read_log(csv)
            row = []
            for name, peaks in (
                ("residual", residual_peaks(meas, model)),
                ("transfer", transfer_peaks(meas)),
            ):
                top = peaks[:TOP]
                hit = any(abs(fr / f_true - 1) <= 0.1 for _, fr in top)
                hits[name] += hit
                row.append(
                    f"{name} {'HIT ' if hit else 'miss'} " + " ".join(f"{fr:.1f}(z{z:.0f})" for z, fr in top)
                )
            total += 1
            print(
                f"{csv.parent.parent.name}/{csv.stem:<34} {truth['sample_rate_hz']:>5} Hz "
                f"{truth['controller']:<9}"
                f" belt {f_true:5.1f} Hz  " + "  ".join(row),
                flush=True,
            )
    print(
        f"\n{total} logs: a top-{TOP} peak within 10 % of the belt: "
        f"residual spectrum {hits['residual']}/{total}, "
        f"command→acceleration transfer {hits['transfer']}/{total}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
