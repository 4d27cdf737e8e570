"""Blind matrix: seeded truth logs from an independent simulator, and a score of the workbench's CLI on them.

    .venv/bin/python bench/blind_matrix.py generate --out DIR [--jobs 1] [--only clean,gravity]
    .venv/bin/python bench/blind_matrix.py score --data DIR --split dev [--limit N] [--jobs 2]
                                               [--only clean,gravity] [--report FILE] [--params-only]

The truth generator is ``tests/truthgen`` (imports nothing from ``tracker``). Scoring runs the
project's command line as an outside user would (the user knows the axis and the gain only):
``tracker model diagnose FILE --axis A --gain K --json``; for pairs a second round as a user
makes it: ``fit --effects <first verdict>``, then ``diagnose`` of that fitted model (``--set``);
and ``tracker model fit FILE --axis A --gain K --effects <true hidden> --json --no-keep`` for the
parameters (plus ``delay`` on a log with a computational latency: :func:`fit_effects`),
compared with the truth as the log sees it (:func:`seen_by_log`) and split by the fit's own
"poorly determined" flag. The heldout split is for the final evaluation only.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

EFFECTS = (
    "coulomb_asymmetry",
    "viscous_asymmetry",
    "offset",
    "stiction",
    "gravity",
    "delay",
    "saturation",
    "ripple",
    "backlash",
    "compliance",
)
# A verdict of one of these stands for the other (both are a constant torque bias per direction).
EQUIVALENT = {"offset": "coulomb_asymmetry", "coulomb_asymmetry": "offset"}
PHASES = ("gravity.phase", "ripple.phase")
BASE_PARAMS = ("inertia.J", "viscous.b", "coulomb.torque")
DEFAULT_TRACKER = ROOT / ".venv" / "bin" / "tracker"


# ----------------------------------------------------------------------------------- generate


def _generate_one(args: tuple[str, str]) -> tuple[str, float, int, str]:
    case_id, out = args
    from tests.truthgen.csvio import write_case
    from tests.truthgen.matrix import generate_case

    t0 = time.perf_counter()
    try:
        log, truth = generate_case(case_id)
    except RuntimeError as exc:
        return case_id, time.perf_counter() - t0, -1, str(exc)
    write_case(out, log, truth)
    return case_id, time.perf_counter() - t0, int(truth["attempt"]), ""


def _selected(group_of: dict[str, tuple[str, ...]], only: str) -> set[str]:
    want = {w.strip() for w in only.split(",") if w.strip()}
    out = set()
    for cid, hidden in group_of.items():
        label = "+".join(hidden) or "clean"
        if not want or label in want or cid in want or any(h in want for h in hidden):
            out.add(cid)
    return out


def cmd_generate(a: argparse.Namespace) -> int:
    from tests.truthgen.matrix import build_matrix

    cases = build_matrix()
    keep = _selected({c.id: c.hidden for c in cases}, a.only)
    ids = [c.id for c in cases if c.id in keep]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results: list[tuple[str, float, int, str]] = []
    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            for r in ex.map(_generate_one, [(i, str(out)) for i in ids]):
                results.append(r)
                print(f"{r[0]:32s} {r[1]:6.2f} s  attempt {r[2]} {r[3]}", flush=True)
    else:
        for i in ids:
            r = _generate_one((i, str(out)))
            results.append(r)
            print(f"{r[0]:32s} {r[1]:6.2f} s  attempt {r[2]} {r[3]}", flush=True)
    wall = time.perf_counter() - t0
    failed = [r for r in results if r[2] < 0]
    splits = Counter(next(c.split for c in cases if c.id == r[0]) for r in results if r[2] >= 0)
    print(
        f"\n{len(results) - len(failed)} logs written to {out} ({dict(splits)}) "
        f"in {wall:.0f} s wall, {a.jobs} job(s)"
    )
    for r in failed:
        print(f"FAILED {r[0]}: {r[3]}")
    return 1 if failed else 0


# -------------------------------------------------------------------------------------- score


def run_cli(tracker: str, args: list[str]) -> tuple[dict[str, Any], float]:
    """Run ``tracker <args> --json``; returns (parsed JSON or {"error": ...}, wall seconds).

    It runs in the tracker script's own folder, not this checkout's: a wrapper that runs another
    checkout's code with ``python -m tracker`` and PYTHONPATH would otherwise import this
    checkout's ``tracker`` (``-m`` puts the working directory first on the path)."""
    t0 = time.perf_counter()
    try:
        out = subprocess.run(
            [tracker, *args, "--json"],
            capture_output=True,
            text=True,
            timeout=900,
            cwd=Path(tracker).resolve().parent,
        )
    except subprocess.TimeoutExpired:
        return {"error": "timeout"}, time.perf_counter() - t0
    dt = time.perf_counter() - t0
    if out.returncode != 0:
        lines = (out.stderr or out.stdout).strip().splitlines() or ["?"]
        return {"error": lines[-1][:300]}, dt
    try:
        return json.loads(out.stdout), dt
    except json.JSONDecodeError:
        return {"error": "unparsable JSON: " + out.stdout[:200]}, dt


def _verdict(d: dict[str, Any], missing: list[str], where: str) -> str:
    if "error" in d:
        return "error"
    if "verdict" not in d:
        missing.append(f"{where}: verdict")
        return "error"
    v = d["verdict"]
    return "none" if v is None else str(v)


def _match(verdict: str, effect: str) -> bool:
    return verdict == effect or EQUIVALENT.get(effect) == verdict


def seen_by_log(truth: dict[str, Any]) -> dict[str, float]:
    """The true parameters as a fit of the log itself must see them (the log's conventions).

    The truth generator records the physical values; two of them are measured on the log in a
    convention that differs, and comparing like with like needs them translated (README,
    "Logging convention"; tests/truthgen/README.md):

    * ``delay.seconds``: the logged ``u`` at row i is applied from t_i + latency_samples·T + delay
      (``latency_samples`` = 1 is the controller's one-sample computational latency, which the
      workbench reports as part of the lag). The lag a fit of the log can find is the sum; a log
      with a latency and no hidden delay has a lag of one sample (see :func:`fit_effects`).
    * ``gravity.phase``, ``ripple.phase``: a truncating encoder reports floor(θ/q)·q, on average
      θ − q/2, so every angle of the log is shifted by −q/2 and a torque sin(nθ + φ) reads as
      sin(nθ_log + φ + n·q/2) in the log's angles (the encoder's zero is a convention, n·q/2 is
      up to 0.25 rad for ripple at 40 cycles on a 500-count encoder). A rounding encoder is
      centred.

    Every other parameter is compared as recorded.
    """
    p = {k: float(v) for k, v in truth["params"].items()}
    latency_s = int(truth.get("latency_samples", 0)) / float(truth["sample_rate_hz"])
    if "delay.seconds" in p or latency_s > 0:
        p["delay.seconds"] = p.get("delay.seconds", 0.0) + latency_s
    if truth.get("encoder_mode") == "truncate":
        half = 0.5 * p.get("quantization.step", 0.0)
        if "gravity.phase" in p:
            p["gravity.phase"] += half
        if "ripple.phase" in p:
            p["ripple.phase"] += p["ripple.cycles_per_rev"] * half
    for k in PHASES:
        if k in p:
            p[k] = (p[k] + math.pi) % (2.0 * math.pi) - math.pi
    return p


def fit_effects(truth: dict[str, Any]) -> list[str]:
    """The effects the parameter fit is given: the hidden ones, plus ``delay`` on a log with a
    computational latency (its true structure has a lag of latency_samples·T, which the README
    tells users to add as ``delay.seconds``; fitting J, b, Fc without it misspecifies the model
    and is not what "fit with the true structure" means)."""
    hidden = list(truth["hidden"])
    if int(truth.get("latency_samples", 0)) > 0 and "delay" not in hidden:
        hidden.append("delay")
    return hidden


#: The score's name of delay.seconds fitted on a log whose only lag is the computational latency.
LATENCY_KEY = "latency as delay.seconds"


def _param_error(name: str, fitted: float, true: float) -> dict[str, float]:
    if name in PHASES:
        e = (fitted - true + math.pi) % (2.0 * math.pi) - math.pi
        return {"abs_rad": abs(e), "ok": float(abs(e) <= 0.1)}
    if name == "delay.seconds":
        e = 1e3 * (fitted - true)
        return {"abs_ms": abs(e), "signed_ms": e, "ok": float(abs(e) <= 1.0)}
    rel = 100.0 * (fitted - true) / abs(true) if true != 0 else float("inf")
    return {"abs_pct": abs(rel), "signed_pct": rel, "ok": float(abs(rel) <= 10.0)}


def _candidate(d: dict[str, Any], effect: str) -> dict[str, Any] | None:
    for c in d.get("candidates") or []:
        if isinstance(c, dict) and c.get("effect") == effect:
            return c
    return None


def _detectability(csv: Path, truth: dict[str, Any]) -> dict[str, Any]:
    """Whether the log resolves its hidden effect at all (``bench/detectability.py``)."""
    from bench.detectability import detectability
    from tests.truthgen.csvio import read_csv

    t, u, theta = read_csv(csv)
    return detectability(truth, t, u, theta)


def score_one(csv: Path, tracker: str, params_only: bool = False, params: bool = True) -> dict[str, Any]:
    """Score one log: diagnose (two rounds for pairs), then fit with the true hidden effects
    (``params_only``: the fit alone; ``params`` False: the diagnosis alone)."""
    truth = json.loads(csv.with_suffix(".json").read_text())
    hidden: list[str] = truth["hidden"]
    base = ["--axis", truth["axis"], "--gain", repr(truth["gain_nm_per_v"])]
    missing: list[str] = []
    rec: dict[str, Any] = {
        "id": truth["id"],
        "hidden": hidden,
        "label": "+".join(hidden) or "clean",
        "axis": truth["axis"],
        "rate_hz": truth["sample_rate_hz"],
        "latency_samples": truth["latency_samples"],
        "friction_law": truth["friction_law"],
        "controller": truth["controller"],
        "encoder_counts_per_rev": truth["encoder_counts_per_rev"],
    }
    rec["detectability"] = _detectability(csv, truth)
    if not params_only:
        _score_diagnosis(csv, tracker, truth, base, rec, missing)
    if params:
        _score_fit(csv, tracker, truth, base, rec, missing)
    rec["missing_keys"] = missing
    return rec


def _score_diagnosis(
    csv: Path, tracker: str, truth: dict[str, Any], base: list[str], rec: dict[str, Any], missing: list[str]
) -> None:
    hidden: list[str] = truth["hidden"]
    d1, t1 = run_cli(tracker, ["model", "diagnose", str(csv), *base])
    v1 = _verdict(d1, missing, "diagnose")
    rec.update(
        verdict=v1, diagnose_s=t1, fit_percent_base=d1.get("fit_percent"), diagnose_notes=d1.get("notes")
    )
    if "error" in d1:
        rec["diagnose_error"] = d1["error"]
    elif "candidates" not in d1:
        missing.append("diagnose: candidates")
    chosen = _candidate(d1, v1) if v1 not in ("none", "error") else None
    if chosen is not None:
        rec["verdict_evidence"] = chosen.get("evidence")
        rec["verdict_fit_percent"] = chosen.get("fit_percent")
        rec["verdict_params"] = chosen.get("params")
    rec["candidates"] = [
        {k: c.get(k) for k in ("effect", "fit_percent", "significant", "evidence")}
        for c in (d1.get("candidates") or [])
        if isinstance(c, dict)
    ]
    rec["right_first"] = bool(hidden) and any(_match(v1, e) for e in hidden)
    rec["false_alarm"] = (not hidden) and v1 not in ("none", "error")
    if len(hidden) == 2:
        found = [e for e in hidden if _match(v1, e)]
        v2 = "not_run"
        if v1 not in ("none", "error"):
            # As a user would: add the verdict and refit everything (``fit --effects``), then
            # diagnose the refitted model (its values passed with ``--set``).
            f1, tf = run_cli(tracker, ["model", "fit", str(csv), *base, "--effects", v1, "--no-keep"])
            fitted = f1.get("params") if isinstance(f1.get("params"), dict) else {}
            sets = [a for k, v in fitted.items() for a in ("--set", f"{k}={v!r}")]
            d2, t2 = run_cli(tracker, ["model", "diagnose", str(csv), *base, "--effects", v1, *sets])
            v2 = _verdict(d2, missing, "diagnose round 2")
            rec["diagnose2_s"] = t2 + tf
            if "error" in d2:
                rec["diagnose2_error"] = d2["error"]
            found += [e for e in hidden if _match(v2, e) and e not in found]
        rec["verdict2"] = v2
        rec["pair_found"] = len(set(found)) == 2 or (
            set(hidden) == {"offset", "coulomb_asymmetry"} and v1 != v2 and {v1, v2} <= set(hidden)
        )


def _score_fit(
    csv: Path, tracker: str, truth: dict[str, Any], base: list[str], rec: dict[str, Any], missing: list[str]
) -> None:
    """Fit with the true hidden effects (nothing kept) and compare with :func:`seen_by_log`."""
    hidden: list[str] = truth["hidden"]
    fitted_effects = fit_effects(truth)
    effects = ["--effects", ",".join(fitted_effects)] if fitted_effects else []
    f, tf = run_cli(tracker, ["model", "fit", str(csv), *base, *effects, "--no-keep"])
    rec["fit_s"] = tf
    if "error" in f:
        rec["fit_error"] = f["error"]
        return
    rec["fit_percent"] = f.get("fit_percent")
    rec["fit_elapsed_s"] = f.get("elapsed_s")
    rec["fit_effects"] = fitted_effects
    rec["fitted"] = f.get("params")
    rec["fitted_stderr"] = f.get("stderr")
    rec["fitted_correlated"] = f.get("correlated")
    fp = f.get("params")
    if not isinstance(fp, dict):
        missing.append("fit: params")
        fp = {}
    flags = {
        c.get("name"): bool(c.get("poorly_determined"))
        for c in f.get("certainty") or []
        if isinstance(c, dict)
    }
    true = seen_by_log(truth)
    errs: dict[str, dict[str, float]] = {}
    names = [k for k in truth["params"] if k.split(".")[0] in hidden] + list(BASE_PARAMS)
    if "delay" in fitted_effects and "delay" not in hidden:
        names.append("delay.seconds")
    for k in names:
        if k not in fp:
            missing.append(f"fit: params[{k}]")
            continue
        key = LATENCY_KEY if k == "delay.seconds" and "delay" not in hidden else k
        try:
            errs[key] = _param_error(k, float(fp[k]), true[k])
        except (TypeError, ValueError):
            missing.append(f"fit: params[{k}] not a number")
            continue
        # the fit's own verdict on this parameter (phases: their amplitude's flag)
        flag_key = {"gravity.phase": "gravity.torque", "ripple.phase": "ripple.amplitude"}.get(k, k)
        errs[key]["flagged"] = float(flags.get(k, False) or flags.get(flag_key, False))
    rec["param_errors"] = errs


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k/n."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    den = 1.0 + z * z / n
    c = (p + z * z / (2 * n)) / den
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, c - h), min(1.0, c + h)


def _pct(k: int, n: int) -> str:
    if n == 0:
        return "   -  "
    lo, hi = wilson(k, n)
    return f"{k:3d}/{n:<3d} = {100 * k / n:5.1f} %  [{100 * lo:4.1f}, {100 * hi:5.1f}]"


def _quantile(xs: list[float], q: float) -> float:
    if not xs:
        return float("nan")
    s = sorted(xs)
    pos = q * (len(s) - 1)
    lo = int(math.floor(pos))
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (pos - lo)


def _min_z() -> float:
    from bench.detectability import MIN_Z

    return MIN_Z


def summarize(recs: list[dict[str, Any]]) -> str:
    """The printed summary of a scoring run (parameters only when no log was diagnosed)."""
    if not any("verdict" in x for x in recs):
        return summarize_params(recs)
    return summarize_diagnosis(recs) + "\n" + summarize_params(recs)


def summarize_diagnosis(recs: list[dict[str, Any]]) -> str:
    """Confusion matrix, false alarms, right first verdicts and pairs."""
    out: list[str] = []
    w = out.append
    rows = ["clean", *EFFECTS]
    cols = ["none", *EFFECTS, "error"]
    abbrev = {c: c[:6] for c in cols}
    abbrev.update(
        coulomb_asymmetry="c_asym", viscous_asymmetry="v_asym", saturation="satur", compliance="compl"
    )
    w("Confusion matrix (rows: truth, single effects and clean; columns: first verdict)")
    w(f"{'':18s}" + "".join(f"{abbrev[c]:>7s}" for c in cols) + "   n")
    for r in rows:
        sel = [x for x in recs if x["label"] == r]
        if not sel:
            continue
        cnt = Counter(x["verdict"] if x["verdict"] in cols else "error" for x in sel)
        w(f"{r:18s}" + "".join(f"{cnt.get(c, 0) or '.':>7}" for c in cols) + f"  {len(sel):3d}")
    other = Counter(x["verdict"] for x in recs if x["verdict"] not in cols)
    if other:
        w(f"(verdicts outside the catalogue: {dict(other)})")
    clean = [x for x in recs if not x["hidden"]]
    w("")
    w("False alarms on clean logs (a verdict where none is hidden), 95 % Wilson interval")
    w(f"  all                {_pct(sum(x['false_alarm'] for x in clean), len(clean))}")
    for key, title in (
        ("latency_samples", "latency"),
        ("friction_law", "friction"),
        ("rate_hz", "rate Hz"),
        ("controller", "controller"),
        ("axis", "axis"),
    ):
        for val in sorted({x[key] for x in clean}, key=str):
            sel = [x for x in clean if x[key] == val]
            w(f"  {title} {str(val):12s}{_pct(sum(x['false_alarm'] for x in sel), len(sel))}")
    singles = [x for x in recs if len(x["hidden"]) == 1]
    w("")
    w("Right first verdict on single effects (offset and coulomb_asymmetry stand for each other)")
    w(f"  all                {_pct(sum(x['right_first'] for x in singles), len(singles))}")
    for e in EFFECTS:
        sel = [x for x in singles if x["hidden"] == [e]]
        if sel:
            w(
                f"  {e:18s} {_pct(sum(x['right_first'] for x in sel), len(sel))}   "
                f"verdicts {dict(Counter(x['verdict'] for x in sel))}"
            )
    rated = [x for x in singles if (x.get("detectability") or {}).get("detectable") is not None]
    if rated:
        w("")
        w(
            "  ... by whether the log resolves the effect (bench/detectability.py: torque signature "
            f"≥ {_min_z():g} standard errors of the log's own noise; backlash wider than the "
            "reading's spread; stiction's torque held above Coulomb at rest)"
        )
        for e in EFFECTS:
            for ok in (True, False):
                sel = [x for x in rated if x["hidden"] == [e] and x["detectability"]["detectable"] is ok]
                if sel:
                    vals = ", ".join(f"{x['detectability']['value']:.2g}" for x in sel)
                    w(
                        f"  {e:18s} {'detectable' if ok else 'undetectable':12s} "
                        f"{_pct(sum(x['right_first'] for x in sel), len(sel))}   "
                        f"({sel[0]['detectability']['measure']} {vals})"
                    )
    pairs = [x for x in recs if len(x["hidden"]) == 2]
    if pairs:
        w("")
        w("Pairs: both effects named in two rounds (diagnose; fit --effects <verdict>; diagnose that fit)")
        w(f"  all                {_pct(sum(x['pair_found'] for x in pairs), len(pairs))}")
        w(f"  first verdict in the pair {_pct(sum(x['right_first'] for x in pairs), len(pairs))}")
        for lab in sorted({x["label"] for x in pairs}):
            sel = [x for x in pairs if x["label"] == lab]
            vs = ", ".join(f"{x['verdict']}→{x.get('verdict2')}" for x in sel)
            w(f"  {lab:30s} {sum(x['pair_found'] for x in sel)}/{len(sel)}   {vs}")
        w(
            "  ... unresolved: the other effect takes away all of one's trace (bench/detectability.py: "
            "a dead band the load never crosses, gravity pressing it on one flank all through the run)"
        )
        for title, want in (("the rest", None), ("unresolved", False)):
            sel = [x for x in pairs if (x.get("detectability") or {}).get("detectable") is want]
            if not sel:
                continue
            w(f"  {title:18s} {_pct(sum(x['pair_found'] for x in sel), len(sel))}")
            if want is False:
                for x in sel:
                    why = ", ".join(
                        f"{e} {r['measure']} {r['value']:.2g}"
                        + (f" flank changes {r['flank_changes']}" if "flank_changes" in r else "")
                        for e, r in (x["detectability"].get("effects") or {}).items()
                        if r.get("detectable") is False
                    )
                    w(f"    {x['id']:30s} {'found' if x['pair_found'] else 'missed'}: {why}")
    return "\n".join(out)


def summarize_params(recs: list[dict[str, Any]]) -> str:
    """Parameter errors (all, and split by the fit's own 'poorly determined' flag), timings."""
    out: list[str] = []
    w = out.append
    clean = [x for x in recs if not x["hidden"]]
    w("")
    w("Parameter errors, fit with the true hidden effects (relative %; phases rad; delay ms)")
    w("  true values as the log sees them (bench/blind_matrix.py seen_by_log: delay includes the")
    w("  latency samples, phases in a truncating encoder's angles); 'determined': not flagged")
    w("  poorly determined by the fit's own uncertainty, ok/n; 'flagged': m, of which ok")
    w(
        f"  {'parameter':30s} {'n':>3s} {'median':>8s} {'p90':>8s} {'share ok':>9s}"
        f" {'determined':>11s} {'flagged':>9s}  ok = within 10 % / 0.1 rad / 1 ms"
    )
    by: dict[str, list[dict[str, float]]] = defaultdict(list)
    by_base: dict[str, list[dict[str, float]]] = defaultdict(list)
    for x in recs:
        for k, e in (x.get("param_errors") or {}).items():
            (
                by_base
                if (k in ("inertia.J", "viscous.b", "coulomb.torque") and k.split(".")[0] not in x["hidden"])
                else by
            )[("clean " if not x["hidden"] else "") + k].append(e)
    for title, table in (("hidden", by), ("base", by_base)):
        for k in sorted(table):
            es = table[k]
            unit = "abs_rad" if "abs_rad" in es[0] else "abs_ms" if "abs_ms" in es[0] else "abs_pct"
            vals = [e[unit] for e in es]
            det = [e for e in es if not e.get("flagged")]
            flg = [e for e in es if e.get("flagged")]
            w(
                f"  {k:30s} {len(es):3d} {_quantile(vals, 0.5):8.3g} {_quantile(vals, 0.9):8.3g} "
                f"{100 * sum(e['ok'] for e in es) / len(es):8.0f} %"
                f" {int(sum(e['ok'] for e in det)):5d}/{len(det):<5d}"
                f" {len(flg):3d} ({int(sum(e['ok'] for e in flg))} ok)"
            )
        if title == "hidden":
            w("  -- base parameters (J, b, Fc) of every log:")
    n_all = sum(len(x.get("param_errors") or {}) for x in recs)
    det_all = [e for x in recs for e in (x.get("param_errors") or {}).values() if not e.get("flagged")]
    w(
        f"  all parameters: {sum(e['ok'] for x in recs for e in (x.get('param_errors') or {}).values()):.0f}"
        f"/{n_all} ok; determined by the log {sum(e['ok'] for e in det_all):.0f}/{len(det_all)} ok; "
        f"flagged as undetermined {n_all - len(det_all)}"
    )
    dts = [x["diagnose_s"] for x in recs if "diagnose_s" in x]
    d2s = [x["diagnose2_s"] for x in recs if "diagnose2_s" in x]
    fts = [x["fit_s"] for x in recs if "fit_s" in x]
    fes = [float(x["fit_elapsed_s"]) for x in recs if x.get("fit_elapsed_s") is not None]
    w("")
    w(
        f"Timing (wall clock per call): diagnose median {_quantile(dts, 0.5):.1f} s, "
        f"max {max(dts, default=float('nan')):.1f} s; second round median {_quantile(d2s, 0.5):.1f} s; "
        f"fit median {_quantile(fts, 0.5):.1f} s, max {max(fts, default=float('nan')):.1f} s "
        f"(the fit itself, without the CLI's start-up: median {_quantile(fes, 0.5):.2f} s, "
        f"max {max(fes, default=float('nan')):.2f} s)"
    )
    errs = [x for x in recs if "diagnose_error" in x or "fit_error" in x]
    if errs:
        w(f"Errors from the CLI: {len(errs)}")
        for x in errs[:10]:
            w(f"  {x['id']}: {x.get('diagnose_error') or ''} {x.get('fit_error') or ''}")
    miss = Counter(m for x in recs for m in x["missing_keys"])
    if miss:
        w(f"Missing keys in the CLI's JSON: {dict(miss)}")
    fa = [x for x in clean if x.get("false_alarm")]
    if fa:
        w("")
        w("Clean logs with a verdict (what the workbench said):")
        for x in fa:
            w(
                f"  {x['id']} {x['friction_law']:8s} lat {x['latency_samples']} {x['rate_hz']:4d} Hz "
                f"{x['controller']:8s} → {x['verdict']} (fit {x.get('fit_percent_base')} → "
                f"{x.get('verdict_fit_percent')}; params {x.get('verdict_params')}): "
                f"{x.get('verdict_evidence')}"
            )
    return "\n".join(out)


def cmd_score(a: argparse.Namespace) -> int:
    folder = Path(a.data).resolve() / a.split
    csvs = sorted(folder.glob("*.csv"))
    if not csvs:
        print(f"no logs in {folder}", file=sys.stderr)
        return 2
    hidden_of = {p: tuple(json.loads(p.with_suffix(".json").read_text())["hidden"]) for p in csvs}
    keep = _selected({p.stem: h for p, h in hidden_of.items()}, a.only)  # by id, label or effect
    csvs = [p for p in csvs if p.stem in keep]
    if a.limit:
        # keep every case type represented: take round-robin over the labels
        by: dict[str, list[Path]] = defaultdict(list)
        for p in csvs:
            by["+".join(hidden_of[p]) or "clean"].append(p)
        rr: list[Path] = []
        while len(rr) < min(a.limit, len(csvs)):
            for lab in sorted(by):
                if by[lab] and len(rr) < a.limit:
                    rr.append(by[lab].pop(0))
        csvs = rr
    print(f"scoring {len(csvs)} logs of {folder} with {a.jobs} job(s)", flush=True)
    t0 = time.perf_counter()
    recs: list[dict[str, Any]] = []
    with ThreadPoolExecutor(a.jobs) as ex:
        for r in ex.map(lambda p: score_one(p, a.tracker, a.params_only, not a.no_params), csvs):
            recs.append(r)
            extra = f" then {r.get('verdict2')}" if "verdict2" in r else ""
            bad = [k for k, e in (r.get("param_errors") or {}).items() if not e["ok"]]
            print(
                f"  {r['id']:32s} → {r.get('verdict', '-')}{extra}  "
                f"({r.get('diagnose_s', 0.0):.1f} s, fit {r.get('fit_s', float('nan')):.1f} s)"
                + (f"  off: {', '.join(bad)}" if bad else ""),
                flush=True,
            )
    wall = time.perf_counter() - t0
    text = summarize(recs)
    print("\n" + text)
    print(f"\n{len(recs)} logs in {wall:.0f} s wall")
    if a.report:
        Path(a.report).write_text(
            json.dumps({"split": a.split, "data": str(a.data), "wall_s": wall, "logs": recs}, indent=1) + "\n"
        )
        print(f"per-log results in {a.report}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate", help="write the matrix's logs and truths")
    g.add_argument("--out", required=True)
    g.add_argument("--jobs", type=int, default=1)
    g.add_argument("--only", default="", help="labels, effects or ids, comma-separated")
    s = sub.add_parser("score", help="run the workbench CLI on a split and score it")
    s.add_argument("--data", required=True)
    s.add_argument("--split", required=True, choices=["dev", "heldout"])
    s.add_argument("--limit", type=int, default=0)
    s.add_argument("--jobs", type=int, default=2)
    s.add_argument(
        "--only", default="", help="labels (clean, gravity, gravity+delay) or effects, comma-separated"
    )
    s.add_argument("--report", default="")
    s.add_argument(
        "--params-only", action="store_true", help="only the fit with the true effects (no diagnosis)"
    )
    s.add_argument("--no-params", action="store_true", help="diagnosis only: no fit with the true effects")
    s.add_argument("--tracker", default=os.environ.get("TRACKER_CLI", str(DEFAULT_TRACKER)))
    a = ap.parse_args()
    return cmd_generate(a) if a.cmd == "generate" else cmd_score(a)


if __name__ == "__main__":
    raise SystemExit(main())
