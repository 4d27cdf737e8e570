"""The engine loop on the simulated rig: pointing, tracking, telemetry, jog, gains, recording."""

import asyncio
import math

import pytest

from tracker.control.gains import ObserverPdGains
from tracker.drivers.sim import SimDriver
from tracker.engine import Engine, TelemetrySnapshot
from tracker.errors import ConfigError, DriverFault
from tracker.targets import FunctionTarget, Target


def run(engine: Engine, seconds: float) -> None:
    asyncio.run(engine.run(realtime=False, duration_s=seconds))


def test_point_moves_both_axes_there_and_reports_manual_mode() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.point(math.radians(30.0), math.radians(-10.0))
    run(e, 1.5)
    assert drv.load_angle_rad("pan") == pytest.approx(math.radians(30.0), abs=math.radians(0.1))
    assert drv.load_angle_rad("tilt") == pytest.approx(math.radians(-10.0), abs=math.radians(0.1))
    s = e.status()
    assert s.mode == "manual" and s.t_s == pytest.approx(1.5)


def test_point_outside_a_soft_limit_is_refused_naming_it() -> None:
    e = Engine(SimDriver())
    with pytest.raises(ConfigError, match="tilt.*45"):
        e.point(0.0, math.radians(50.0))


def test_tracking_follows_a_moving_source() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.set_target_source(FunctionTarget(lambda t: (0.3 * math.sin(2 * math.pi * 0.5 * t), 0.1)))
    e.set_tracking(True)
    run(e, 3.0)
    expected = 0.3 * math.sin(2 * math.pi * 0.5 * 3.0)
    # One 10 ms chunk of latency at most 0.3·π·0.01 rad behind.
    assert drv.load_angle_rad("pan") == pytest.approx(expected, abs=0.012)
    assert e.status().mode == "tracking"


def test_telemetry_reaches_subscribers_at_100_hz_of_engine_time() -> None:
    e = Engine(SimDriver())
    got: list[TelemetrySnapshot] = []

    async def main() -> None:
        sub = e.subscribe(1000)

        async def consume() -> None:
            async for snap in sub:
                got.append(snap)

        task = asyncio.create_task(consume())
        await e.run(realtime=False, duration_s=0.5)
        await task

    asyncio.run(main())
    assert len(got) == 50
    assert got[-1].t_s == pytest.approx(0.5)


def test_slow_subscriber_keeps_only_the_newest() -> None:
    e = Engine(SimDriver())
    sub = e.subscribe(maxsize=3)
    for _ in range(10):
        e.step_chunk()
    assert sub.dropped == 7


def test_jog_moves_then_stops_by_itself_after_the_timeout() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.jog("pan", 0.5, timeout_s=0.2)
    run(e, 1.0)
    # 0.2 s at 0.5 rad/s ≈ 0.1 rad, then it stays put.
    assert drv.load_angle_rad("pan") == pytest.approx(0.1, abs=0.012)


def test_unstable_gains_are_refused_with_their_margins() -> None:
    e = Engine(SimDriver())
    with pytest.raises(ConfigError, match="phase margin"):
        e.set_gains("pan", ObserverPdGains(400.0, 0.2, 0.0, 40.0))
    good = e.gains("pan")
    report = e.set_gains("pan", good)
    assert report.ok and report.phase_margin_deg >= 45.0


def test_recording_gives_a_log_per_axis() -> None:
    e = Engine(SimDriver())
    e.point(0.2, 0.1)
    e.start_recording()
    run(e, 0.5)
    logs = e.stop_recording()
    assert set(logs) == {"pan", "tilt"}
    assert logs["pan"].n == 500 and logs["pan"].dt_s == pytest.approx(1e-3)
    assert logs["pan"].theta_rad[-1] > 0.1


class ProtocolOnly:
    """The rig seen only through the MotorDriver Protocol (no compiled fast path)."""

    def __init__(self, rig: SimDriver) -> None:
        self.rig = rig
        self.axes = rig.axes
        self.sample_period_s = rig.sample_period_s

    @property
    def sample_time_s(self) -> float:
        return self.rig.sample_time_s

    @property
    def enabled(self) -> bool:
        return self.rig.enabled

    def enable(self) -> None:
        self.rig.enable()

    def disable(self) -> None:
        self.rig.disable()

    def command(self, axis: str, volts: float) -> None:
        self.rig.command(axis, volts)

    def read_encoder(self, axis: str) -> float:
        return self.rig.read_encoder(axis)

    def tick(self) -> None:
        self.rig.tick()

    def faults(self) -> tuple[str, ...]:
        return self.rig.faults()

    def clear_faults(self) -> None:
        self.rig.clear_faults()


def test_a_driver_without_the_fast_path_gives_the_same_run() -> None:
    fast_rig, slow_rig = SimDriver(), SimDriver()
    fast, slow = Engine(fast_rig), Engine(ProtocolOnly(slow_rig))  # type: ignore[arg-type]
    for e in (fast, slow):
        e.point(math.radians(15.0), math.radians(5.0))
        run(e, 0.3)
    for axis in ("pan", "tilt"):
        assert slow_rig.load_angle_rad(axis) == pytest.approx(fast_rig.load_angle_rad(axis), abs=1e-12)


def test_a_latched_fault_shows_as_fault_mode_and_the_rig_stops_driving() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.point(math.radians(40.0), 0.0)
    run(e, 0.1)
    drv.latch_fault("pan: amplifier over-temperature (injected)")
    snap = e.step_chunk()
    assert snap.mode == "fault" and snap.pan_u_v == 0.0 and snap.tilt_u_v == 0.0
    assert "over-temperature" in e.status().faults[0]


def test_re_enabling_after_a_disable_holds_where_the_axis_is() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.set_tracking(True)
    e.set_target_source(FunctionTarget(lambda t: (0.4, 0.0)))
    run(e, 1.0)
    drv.disable()
    e.set_tracking(False)
    run(e, 0.2)
    assert e.status().mode == "disabled"
    here = drv.load_angle_rad("pan")
    drv.enable()
    run(e, 0.5)
    assert e.status().mode == "hold"
    assert drv.load_angle_rad("pan") == pytest.approx(here, abs=1e-3)


def test_tracking_without_a_target_holds() -> None:
    e = Engine(SimDriver())
    e.set_target_source(FunctionTarget(lambda t: None))
    e.set_tracking(True)
    run(e, 0.1)
    assert e.status().mode == "hold"


def test_jog_faster_than_the_axis_rate_limit_is_refused() -> None:
    e = Engine(SimDriver())
    with pytest.raises(ConfigError, match="rate limit"):
        e.jog("tilt", 10.0)


def test_realtime_mode_keeps_pace_with_the_wall_clock() -> None:
    import time

    e = Engine(SimDriver())
    e.step_chunk()  # first chunk outside the timing (compiled code is loaded)
    t0 = time.perf_counter()
    asyncio.run(e.run(realtime=True, duration_s=0.3))
    assert time.perf_counter() - t0 >= 0.29
    assert e.status().t_s == pytest.approx(0.31)


def test_jog_rate_zero_is_the_release_of_the_button() -> None:
    drv = SimDriver()
    e = Engine(drv)
    e.jog("tilt", -0.4, timeout_s=5.0)
    run(e, 0.25)
    e.jog("tilt", 0.0)
    run(e, 0.75)
    # ≈ 0.25 s at −0.4 rad/s, then held.
    assert drv.load_angle_rad("tilt") == pytest.approx(-0.1, abs=0.012)


def test_a_talker_source_reports_who_and_where_it_heard() -> None:
    e = Engine(SimDriver())
    e.set_target_source(
        FunctionTarget(
            lambda t: Target(0.2, 0.05, talker="alice", azimuth_rad=0.21, elevation_rad=0.04), "audio"
        )
    )
    e.set_tracking(True)
    sub = e.subscribe()
    e.step_chunk()  # the driver is still disabled: the estimate is reported all the same
    snap = sub.get_nowait()
    assert snap is not None and snap.source == "audio" and snap.estimate_azimuth_rad == 0.21
    assert e.status().active_talker == "alice" and e.status().mode == "disabled"
    e.driver.enable()
    run(e, 0.6)
    assert e.status().mode == "tracking" and e.status().pan_rad == pytest.approx(0.2, abs=1e-3)


def test_redesign_on_a_fitted_model_changes_the_gains_and_keeps_margins() -> None:
    from tracker.plant.model import AxisModel

    e = Engine(SimDriver())
    before = e.gains("tilt")
    heavier = AxisModel.for_axis("tilt").with_params({"inertia.J": 0.003})
    design = e.set_model("tilt", heavier)
    assert e.model("tilt") is heavier and e.gains("tilt") == design.gains
    assert design.report.phase_margin_deg >= 45.0
    # Twice the inertia, same bandwidth: about twice the stiffness.
    assert e.gains("tilt").kp_v_per_rad == pytest.approx(2.05 * before.kp_v_per_rad, rel=0.05)  # type: ignore[union-attr]
    faster = e.set_model("tilt", heavier, crossover_hz=16.0)
    assert faster.report.crossover_hz == pytest.approx(16.0, rel=0.05)


def test_a_standing_fault_refuses_pointing_jogging_and_tracking_until_cleared() -> None:
    """Issue #11 item 3: after a latched fault the engine refuses what would move the axes
    (DriverFault, the service's 503), ends the manual override, and allows stopping."""
    drv = SimDriver()
    e = Engine(drv)
    drv.enable()
    e.point(math.radians(40.0), 0.0)
    run(e, 0.2)
    drv.latch_fault("pan: over-travel at -95.3° (injected)")
    run(e, 0.05)
    with pytest.raises(DriverFault, match="over-travel.*refused until the fault is cleared"):
        e.point(0.0, 0.0)
    with pytest.raises(DriverFault, match="over-travel"):
        e.jog("pan", 0.2)
    with pytest.raises(DriverFault, match="over-travel"):
        e.set_tracking(True)
    e.jog("pan", 0.0)  # stopping is always allowed
    e.set_tracking(False)
    assert e.status().mode == "fault"
    here = drv.load_angle_rad("pan")
    drv.clear_faults()
    drv.enable()
    run(e, 0.3)
    # The override ended with the fault (the stop held the axes where they were): no move to 40°.
    assert drv.load_angle_rad("pan") == pytest.approx(here, abs=math.radians(0.5))
    e.point(0.0, 0.0)
    run(e, 1.0)
    assert drv.load_angle_rad("pan") == pytest.approx(0.0, abs=math.radians(0.1))


def test_after_an_over_travel_the_axis_rests_on_its_end_stop_and_comes_back_once_cleared() -> None:
    drv = SimDriver()
    e = Engine(drv)
    drv.enable()
    drv.set_angle("pan", math.radians(-97.0))  # past the end stop (−95°)
    run(e, 0.05)
    assert drv.faults() and "over-travel at -97.0°" in drv.faults()[0]
    # Against the stop (the guard's last push, still in the amplifier, moved it a hair inward).
    assert math.radians(-95.0) - 1e-9 <= drv.load_angle_rad("pan") < math.radians(-94.9)
    drv.clear_faults()
    drv.enable()
    run(e, 1.5)
    assert not drv.faults()
    assert math.radians(-90.0) < drv.load_angle_rad("pan") < math.radians(-89.0)


def test_a_driver_that_is_not_a_driver_is_refused_by_name() -> None:
    # A driver written before the interface grew sample_time_s: refused, not run as nothing.
    old = type("OldDriver", (), {k: v for k, v in ProtocolOnly.__dict__.items()
                                 if k not in ("sample_time_s", "__dict__", "__weakref__")})
    with pytest.raises(ConfigError, match="OldDriver.*sample_time_s"):
        Engine(old(SimDriver()))


def test_a_slow_first_chunk_is_the_warm_ups_lateness_not_the_loops() -> None:
    """Bug: with a cold numba cache the first chunk came 10-15 s late and the status' largest
    lateness kept it for the service's life. The first second of ticks is the warm-up."""
    import time

    from tracker.engine import WARM_UP_S

    e = Engine(SimDriver())
    original, calls = e.step_chunk, []

    def slow_first() -> TelemetrySnapshot:
        calls.append(1)
        if len(calls) == 1:
            time.sleep(0.6)  # as a first chunk that compiles its kernels
        return original()

    e.step_chunk = slow_first  # type: ignore[method-assign]
    asyncio.run(e.run(realtime=True, duration_s=1.5))
    t = e.timing()
    assert t.warm_up_ticks == math.ceil(WARM_UP_S / t.period_s) < t.ticks
    assert t.warm_up_max_lateness_s >= 0.55  # the slow first chunk, reported apart
    assert t.max_lateness_s < 0.55 and t.restarts >= 1  # ... not as the loop's worst tick
