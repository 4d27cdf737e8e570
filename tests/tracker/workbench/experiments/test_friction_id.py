"""The friction-ID job on the simulated rig: it must recover the rig's friction, per direction."""

from __future__ import annotations

import json

import pytest

from tracker.cli import main
from tracker.drivers.sim import SimDriver
from tracker.errors import DataError, DriverFault, JobCancelled
from tracker.plant.model import AxisModel
from tracker.workbench.experiments.friction_id import run_friction_id


def _rig(axis: str, effects: tuple[str, ...] = (), params: dict[str, float] | None = None) -> SimDriver:
    other = "tilt" if axis == "pan" else "pan"
    return SimDriver(
        {
            axis: AxisModel.for_axis(axis, ["quantization", *effects], params or {}),
            other: AxisModel.for_axis(other, ["quantization"]),
        }
    )


@pytest.mark.parametrize("axis", ["pan", "tilt"])
def test_recovers_the_seed_friction_of_each_axis(axis: str) -> None:
    res = run_friction_id(_rig(axis), axis)
    true = AxisModel.for_axis(axis).params
    for line in (res.positive, res.negative):
        assert line.viscous_nm_s_per_rad == pytest.approx(true["viscous.b"], rel=0.03)
        assert line.coulomb_nm == pytest.approx(true["coulomb.torque"], rel=0.01)
    assert not res.shows_stiction()


def test_recovers_direction_dependent_friction() -> None:
    # The seed's measured pan values (App. A): Coulomb 0.0417 / 0.0466 N·m, viscous 1.1e-3 / 1.3e-3.
    params = {
        "coulomb.torque": 0.0417,
        "coulomb_asymmetry.negative": 0.0466,
        "viscous.b": 1.1e-3,
        "viscous_asymmetry.negative": 1.3e-3,
    }
    res = run_friction_id(_rig("pan", ("coulomb_asymmetry", "viscous_asymmetry"), params), "pan")
    for name, value in res.params.items():
        assert value == pytest.approx(params[name], rel=0.03), name


def test_break_away_above_coulomb_reveals_stiction_but_a_delay_does_not() -> None:
    res = run_friction_id(_rig("pan", ("stiction",), {"stiction.static_torque": 0.08}), "pan")
    assert res.shows_stiction()
    assert res.breakaway_positive_nm == pytest.approx(0.08, rel=0.05)
    assert res.positive.coulomb_nm == pytest.approx(0.052, rel=0.02)
    delayed = run_friction_id(_rig("pan", ("delay",), {"delay.seconds": 0.015}), "pan")
    assert not delayed.shows_stiction()
    assert delayed.positive.coulomb_nm == pytest.approx(0.052, rel=0.02)


def test_progress_rises_to_one_and_cancel_stops_the_job() -> None:
    seen: list[float] = []
    run_friction_id(_rig("tilt"), "tilt", voltages_per_direction=4, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == pytest.approx(1.0)
    driver = _rig("tilt")
    calls = iter(range(10**6))
    with pytest.raises(JobCancelled):
        run_friction_id(driver, "tilt", cancel=lambda: next(calls) > 20)
    assert not driver.enabled


def test_cli_json_has_per_direction_friction_and_plot_data(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(
        [
            "friction-id",
            "--axis",
            "pan",
            "--json",
            "--voltages",
            "5",
            "--effects",
            "coulomb_asymmetry",
            "--set",
            "coulomb_asymmetry.negative=0.07",
        ]
    )
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["negative"]["coulomb_nm"] == pytest.approx(0.07, rel=0.02)
    assert out["positive"]["coulomb_nm"] == pytest.approx(0.052, rel=0.02)
    assert len(out["plot"]["velocity_rad_s"]) == len(out["plot"]["torque_nm"]) >= 6


def test_cli_rejects_an_unknown_hidden_effect(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["friction-id", "--axis", "pan", "--effects", "warp_drive"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "warp_drive" in err and "\n" == err[-1] and err.count("\n") == 1


def test_an_unbalanced_axis_gets_an_error_that_names_the_likely_cause() -> None:
    """Regression (practice rig hiding gravity): the job failed with only 'widen the voltage range'."""
    rig = _rig("pan", ("gravity",), {"gravity.torque": 0.05, "gravity.phase": 1.0})
    with pytest.raises(DataError, match="position-dependent torque"):
        run_friction_id(rig, "pan")


class _SlippingHost:
    """The rig seen by a host that falls behind: every third sample the board's time (and the
    twin) moves on two periods while the host counts one, as a loaded host's serial driver does
    against a board that runs in real time. Everything else is the twin's."""

    def __init__(self, rig: SimDriver) -> None:
        self._rig = rig
        self._n = 0

    def __getattr__(self, name: str) -> object:
        return getattr(self._rig, name)

    @property
    def sample_period_s(self) -> float:
        return self._rig.sample_period_s

    @property
    def sample_time_s(self) -> float:
        return self._rig.sample_time_s

    def tick(self) -> None:
        self._n += 1
        self._rig.tick()
        if self._n % 3 == 0:
            self._rig.tick()  # the command held one period longer: the host slipped


def test_velocities_come_from_the_device_clock_when_the_host_slips() -> None:
    # With the nominal period the slipped run's velocities come out 4/3 too fast (viscous ~25 %
    # low): the board's time stamps give the rig's friction whatever the host's timing.
    res = run_friction_id(_SlippingHost(_rig("pan")), "pan")  # type: ignore[arg-type]
    true = AxisModel.for_axis("pan").params
    for line in (res.positive, res.negative):
        assert line.viscous_nm_s_per_rad == pytest.approx(true["viscous.b"], rel=0.05)
        assert line.coulomb_nm == pytest.approx(true["coulomb.torque"], rel=0.03)


class _TripsAfter(_SlippingHost):
    """A rig whose driver latches a fault (the board's watchdog) after ``n`` samples."""

    def __init__(self, rig: SimDriver, n: int) -> None:
        super().__init__(rig)
        self._limit = n

    def tick(self) -> None:
        self._n += 1
        self._rig.tick()

    def faults(self) -> tuple[str, ...]:
        tripped = self._n >= self._limit
        return ("serial:///dev/ttyRIG: the board's watchdog zeroed the command",) if tripped else ()


def test_a_fault_during_the_sweep_stops_it_and_names_the_fault() -> None:
    # Before: the disabled driver's runs all read "did not move" and the job blamed the voltages.
    with pytest.raises(DriverFault, match="watchdog"):
        run_friction_id(_TripsAfter(_rig("pan"), 3000), "pan")  # type: ignore[arg-type]


class _TimingOutHost(_SlippingHost):
    """A rig whose exchanges time out now and then: for 25 samples in every 200 the host gets no
    new reading (the angle and its time stamp stay the last ones) while the rig moves on."""

    def __init__(self, rig: SimDriver) -> None:
        super().__init__(rig)
        self._held: tuple[float, float] | None = None

    def tick(self) -> None:
        self._n += 1
        self._rig.tick()
        frozen = self._n % 200 < 25
        if frozen and self._held is None:
            self._held = (self._rig.read_encoder("pan"), self._rig.sample_time_s)
        elif not frozen:
            self._held = None

    def read_encoder(self, axis: str) -> float:
        return self._held[0] if self._held is not None and axis == "pan" else self._rig.read_encoder(axis)

    @property
    def sample_time_s(self) -> float:
        return self._held[1] if self._held is not None else self._rig.sample_time_s


def test_a_reading_that_did_not_come_is_not_taken_for_a_still_axis() -> None:
    # A frozen reading looked like an axis at rest: the break-away ramp then started while the
    # axis still coasted, took the coast for a break-away, and no constant-voltage run moved.
    res = run_friction_id(_TimingOutHost(_rig("pan")), "pan", voltages_per_direction=5)  # type: ignore[arg-type]
    true = AxisModel.for_axis("pan").params
    for line in (res.positive, res.negative):
        assert line.coulomb_nm == pytest.approx(true["coulomb.torque"], rel=0.05)
        assert line.viscous_nm_s_per_rad == pytest.approx(true["viscous.b"], rel=0.1)
