"""The engine under random operator input: whatever is pointed, jogged, tuned, tracked or offered
as the controller's model, the camera stays inside the soft limits and the engine only ever
refuses with ConfigError."""

import asyncio
import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tracker.control.gains import ObserverPdGains
from tracker.drivers.sim import SimDriver
from tracker.engine import Engine
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.targets import FunctionTarget

LIMIT_RAD = {"pan": math.radians(90.0), "tilt": math.radians(45.0)}
angle = st.floats(-4.0, 4.0)
wild = st.one_of(angle, st.sampled_from([1e6, -1e6]))
# A model fitted to the wrong log: inertia and Coulomb friction each ×0.2–×5 (refused with
# ModelRefused, a ConfigError, once the axis has moved; the guard does not rely on it either way).
factor = st.floats(0.2, 5.0)
operations = st.one_of(
    st.tuples(st.just("model"), st.sampled_from(["pan", "tilt"]), st.tuples(factor, factor)),
    st.tuples(st.just("point"), angle, angle),
    st.tuples(st.just("jog"), st.sampled_from(["pan", "tilt"]), st.floats(-4.0, 4.0)),
    st.tuples(st.just("release"), st.none(), st.none()),
    st.tuples(st.just("track"), wild, wild),
    st.tuples(
        st.just("gains"),
        st.sampled_from(["pan", "tilt"]),
        st.builds(
            ObserverPdGains,
            kp_v_per_rad=st.floats(0.1, 5000.0),
            kd_v_s_per_rad=st.floats(-5.0, 50.0),
            ki_v_per_rad_s=st.floats(0.0, 5000.0),
            observer_bandwidth_hz=st.floats(1.0, 200.0),
        ),
    ),
)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ops=st.lists(operations, min_size=1, max_size=6))
def test_random_operator_input_never_passes_a_soft_limit(ops: list[tuple[str, object, object]]) -> None:
    drv = SimDriver()
    drv.enable()
    e = Engine(drv)
    worst = {"pan": 0.0, "tilt": 0.0}
    pointed = []

    async def run_ops() -> None:
        for op, a, b in ops:
            try:
                if op == "point":
                    e.point(float(a), float(b))  # type: ignore[arg-type]
                    pointed.append(max(abs(float(a)), abs(float(b))))  # type: ignore[arg-type]
                elif op == "jog":
                    e.jog(str(a), float(b), timeout_s=0.3)  # type: ignore[arg-type]
                elif op == "release":
                    e.release()
                elif op == "model":
                    assert isinstance(b, tuple)
                    fj, fc = float(b[0]), float(b[1])
                    base = AxisModel.for_axis(str(a))
                    e.set_model(
                        str(a),
                        base.with_params(
                            {
                                "inertia.J": base.params["inertia.J"] * fj,
                                "coulomb.torque": base.params["coulomb.torque"] * fc,
                            }
                        ),
                    )
                elif op == "track":
                    e.set_target_source(FunctionTarget(lambda t, a=a, b=b: (a, b)))
                    e.set_tracking(True)
                else:
                    e.set_gains(str(a), b)  # type: ignore[arg-type]
            except ConfigError:
                pass
            for _ in range(40):  # 0.4 s per operation, checking the truth every chunk
                e.step_chunk()
                for axis in worst:
                    worst[axis] = max(worst[axis], abs(drv.load_angle_rad(axis)))

    asyncio.run(run_ops())
    if any(p > 0.05 for p in pointed):  # the rig really moved (the test can fail)
        assert max(worst.values()) > 0.02
    for axis, lim in LIMIT_RAD.items():
        assert worst[axis] <= lim, f"{axis} reached {math.degrees(worst[axis]):.3f}°"
