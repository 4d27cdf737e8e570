"""The bench's detectability of a hidden effect (bench/detectability.py) on the generator's logs."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np

from bench.detectability import MIN_Z, detectability
from tests.truthgen.matrix import generate_case

ROOT = Path(__file__).resolve().parents[2]


def _rate(case_id: str, scale: float = 1.0) -> dict[str, object]:
    log, truth = generate_case(case_id)
    truth = copy.deepcopy(truth)
    if scale != 1.0 and "viscous_asymmetry.negative" in truth["params"]:
        p = truth["params"]
        excess = p["viscous_asymmetry.negative"] - p["viscous.b"]
        p["viscous_asymmetry.negative"] = p["viscous.b"] + scale * excess
    return detectability(truth, log.t, log.u, log.theta)


def test_a_viscous_asymmetry_under_the_logs_disturbance_is_undetectable() -> None:
    """The case of the last session's analysis: 5e-4 N·m at 1 rad/s under a 1.6 mN·m disturbance
    low-passed at 0.8 Hz. "No verdict" is the right answer there."""
    r = _rate("viscous_asymmetry-001")
    assert r["measure"] == "z" and r["detectable"] is False
    assert isinstance(r["value"], float) and r["value"] < MIN_Z


def test_the_same_asymmetry_twenty_times_larger_would_be_resolved() -> None:
    """The measure scales with the signature against the same noise (the log is unchanged)."""
    small, large = _rate("viscous_asymmetry-001"), _rate("viscous_asymmetry-001", 20.0)
    assert isinstance(small["value"], float) and isinstance(large["value"], float)
    assert large["value"] > 10.0 * small["value"]
    assert large["detectable"] is True


def test_gravity_that_the_diagnosis_finds_is_detectable_and_clean_logs_are_not_rated() -> None:
    r = _rate("gravity-000")
    assert r["detectable"] is True and isinstance(r["value"], float) and r["value"] >= MIN_Z
    assert _rate("clean-000")["detectable"] is None


def test_a_dead_band_narrower_than_the_readings_spread_is_undetectable() -> None:
    """dev backlash-004: 2.1 counts at 250 Hz; backlash-000: 4.2 counts, resolved."""
    narrow, wide = _rate("backlash-004"), _rate("backlash-000")
    assert narrow["measure"] == "width/spread" and narrow["detectable"] is False
    assert wide["detectable"] is True


def test_detectability_imports_nothing_from_tracker() -> None:
    code = "import sys, bench.detectability; print(any(m.split('.')[0] == 'tracker' for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "False"


def _rate_stiction(case_id: str, seed: int | None = None, excess_scale: float = 1.0) -> dict[str, object]:
    import tests.truthgen.matrix as matrix

    if seed is None:
        log, truth = generate_case(case_id)
    else:
        with matrix.seeded(seed):
            log, truth = generate_case(case_id)
    truth = copy.deepcopy(truth)
    p = truth["params"]
    p["stiction.static_torque"] = p["coulomb.torque"] + excess_scale * (
        p["stiction.static_torque"] - p["coulomb.torque"]
    )
    return detectability(truth, log.t, log.u, log.theta)


def test_stiction_is_rated_by_the_torque_held_above_coulomb_at_rest() -> None:
    """A closed-loop log whose command creeps up to the break-away at each start from rest:
    the torque held above Coulomb is many standard errors of the disturbance and of Coulomb's
    own uncertainty. The same log judged against a break-away at Coulomb holds nothing."""
    r = _rate_stiction("stiction-001")
    assert r["measure"] == "held/noise" and r["detectable"] is True
    assert isinstance(r["value"], float) and r["value"] >= MIN_Z
    assert isinstance(r["rests"], int) and r["rests"] >= 10
    assert isinstance(r["holding"], int) and r["holding"] > 0
    none = _rate_stiction("stiction-001", excess_scale=0.0)
    assert none["value"] == 0.0 and none["detectable"] is False


def test_stiction_under_open_loop_steps_that_never_hold_is_undetectable() -> None:
    """Seed 5151's stiction-005: open-loop steps that either stay below Coulomb or jump past
    the break-away at once. No rest ever holds a torque above Coulomb, so the log cannot tell
    the break-away from Coulomb: "no verdict" is the right answer there."""
    r = _rate_stiction("stiction-005", seed=5151)
    assert r["holding"] == 0 and r["detectable"] is False


def test_a_dead_band_that_gravity_holds_on_one_flank_is_unresolved_in_a_pair() -> None:
    """A pair's dead band is rated by whether the load ever crosses it. The truth's own load and
    motor angles say how often the gap was crossed; the rating from the logged angle must agree
    where it matters: never (gravity presses the load on one flank all through the run, so the
    gap leaves no trace, however wide) against many times."""
    import tests.truthgen.matrix as matrix

    def crossings(log: object, width: float) -> int:
        twist = log.theta_motor - log.theta_load  # type: ignore[attr-defined]
        side = np.where(twist > 0.45 * width, 1, np.where(twist < -0.45 * width, -1, 0))
        held = side[side != 0]
        return int(np.count_nonzero(held[1:] != held[:-1]))

    with matrix.seeded(2411):  # a spent blind set's held-out half (issue 9, session 8)
        held_log, held_truth = matrix.generate_case("backlash+gravity-000")
        free_log, free_truth = matrix.generate_case("backlash+gravity-004")
    held = detectability(held_truth, held_log.t, held_log.u, held_log.theta)
    free = detectability(free_truth, free_log.t, free_log.u, free_log.theta)
    assert crossings(held_log, held_truth["params"]["backlash.width"]) == 0
    assert crossings(free_log, free_truth["params"]["backlash.width"]) > 10
    assert held["detectable"] is False and held["effects"]["backlash"]["flank_changes"] == 0
    # wide against the reading's spread: unresolved only because the load never crosses it
    assert held["effects"]["backlash"]["value"] > 10.0
    assert free["detectable"] is None and free["effects"]["backlash"]["flank_changes"] > 10
    assert free["effects"]["backlash"]["detectable"] is True


def test_pairs_without_a_rating_of_their_own_are_not_rated() -> None:
    assert _rate("coulomb_asymmetry+gravity-001")["detectable"] is None


def test_stiction_behind_a_delay_is_rated_on_the_command_as_it_reaches_the_axis() -> None:
    """Seed 8181's held-out stiction+delay-000 (a spent set, issue 9 session 12): open-loop
    voltage steps of at least 1.3 V (0.096 N·m) against a break-away of 0.090 N·m and an 18 ms
    delay. Every step starts the axis at once, and no rest holds a torque between Coulomb and
    the break-away: the log cannot show the static friction (the true model with it predicts no
    better than without it), so "delay, then nothing" is the right answer there. On the logged
    command each step looked "held" for the delay's length before the start. Dev
    stiction+delay-003 of the same seed (PD + feed-forward, the command creeping up to the
    break-away at each start) is resolvable."""
    import tests.truthgen.matrix as matrix

    with matrix.seeded(8181):
        steps_log, steps_truth = generate_case("stiction+delay-000")
        creep_log, creep_truth = generate_case("stiction+delay-003")
    assert steps_truth["controller"] == "ol_steps" and steps_truth["params"]["delay.seconds"] > 0.01
    steps = detectability(steps_truth, steps_log.t, steps_log.u, steps_log.theta)
    creep = detectability(creep_truth, creep_log.t, creep_log.u, creep_log.theta)
    assert steps["detectable"] is False
    held, crept = steps["effects"]["stiction"], creep["effects"]["stiction"]
    assert held["holding"] == 0 and held["detectable"] is False
    assert crept["detectable"] is True and crept["holding"] > 10


def test_a_step_past_the_break_away_holds_nothing_while_the_axis_travels_to_its_first_count() -> None:
    """The same seed's held-out stiction+delay-002 on a 1000-count encoder: after a step past the
    break-away the axis starts at once but needs about 19 ms to reach the next count. Rated on
    the delayed command over a fixed window ending 4 ms before the reading moved, that travel
    counted as torque held at rest (4 rests "holding", z = 25: detectable). A rest holds a torque
    only when it stayed between Coulomb and the break-away for longer than the axis without
    static friction needs to cover a count; this log has none (the true model with stiction
    predicts its 30 ms windows 4 % worse than without it)."""
    import tests.truthgen.matrix as matrix

    with matrix.seeded(8181):
        log, truth = generate_case("stiction+delay-002")
    pair = detectability(truth, log.t, log.u, log.theta)
    assert pair["effects"]["stiction"]["holding"] == 0 and pair["effects"]["stiction"]["value"] == 0.0


def test_a_fresh_matrix_draws_viscous_asymmetries_the_log_resolves() -> None:
    """Fresh seeds draw the asymmetry as a torque (10–30 % of Coulomb at 1 rad/s) and draw a case
    again until the rater resolves it; the legacy default seed keeps its old, mostly unresolvable
    draw (the case above), so its logs stay reproducible."""
    from tests.truthgen import matrix

    with matrix.seeded(4545):
        for case_id in ("viscous_asymmetry-000", "viscous_asymmetry-004"):
            log, truth = matrix.generate_case(case_id)
            p = truth["params"]
            excess_nm = p["viscous_asymmetry.negative"] - p["viscous.b"]  # at 1 rad/s
            assert 0.1 <= excess_nm / p["coulomb.torque"] <= 0.3
            r = detectability(truth, log.t, log.u, log.theta)
            assert r["detectable"] is True and float(r["value"]) >= MIN_Z, (case_id, r)
