"""Thin adapter between the service and the engine: build the rig and engine from settings, wire
the audio tracker in as the target source, and read what the routes need (limits, the plant
model of an axis, a predicted step response). Everything delegates to ``tracker``; no physics
lives in app/.
"""

from __future__ import annotations

import inspect
import logging
import math
from typing import Any

import numpy as np

from app.settings import Settings
from tracker.errors import ConfigError

log = logging.getLogger("app.rig")

AXES = ("pan", "tilt")


def build_driver(settings: Settings, hidden: Any = None, axis: str = "pan") -> Any:
    """The simulated rig (experiments run on it whatever the live driver is): hidden effects
    from ``settings.rig_config`` (JSON), or the model ``hidden`` on ``axis`` (the practice rig)
    with the seed's model on the other axis."""
    from tracker.drivers.sim import SimDriver, rig_models

    if hidden is not None:
        models = dict(rig_models())
        if not hidden.has("quantization"):
            hidden = hidden.with_effect("quantization")
        models[axis] = hidden
        return SimDriver.from_models(models)
    if settings.rig_config is not None:
        return SimDriver.from_config(settings.rig_config)
    return SimDriver()


def build_camera(settings: Settings) -> Any:
    """The VISCA camera of ``settings.driver``, with the engine's soft limits enforced in the
    driver too (guard margin included), the profile, command rate and steering of the settings."""
    from tracker.drivers.camera_profiles import get_profile
    from tracker.drivers.spec import parse_driver_url
    from tracker.drivers.visca import ViscaCamera

    limits = guard_lines_rad(settings)
    return ViscaCamera(parse_driver_url(settings.driver), get_profile(settings.camera_profile), limits,
                       rate_hz=settings.camera_rate_hz, steering=settings.camera_steering,
                       own_thread=True)  # its command cycle off the web event loop


def guard_lines_rad(settings: Settings) -> dict[str, tuple[float, float]]:
    """The soft-limit guard's lines per axis (rad): the limits less the guard margin."""
    from tracker.control.limits import SoftLimits

    margin = math.radians(settings.guard_margin_deg)
    limits = {}
    for axis in AXES:
        lim = SoftLimits.for_axis(axis, margin)
        limits[axis] = (lim.lower_rad + lim.guard_margin_rad, lim.upper_rad - lim.guard_margin_rad)
    return limits


def build_serial_rig(settings: Settings) -> Any:
    """The DC rig behind the motor controller board of ``settings.driver``: the gear ratios of
    the settings, the soft limits enforced in the driver too (guard margin included)."""
    from tracker.drivers.serial_motor import SerialMotorDriver
    from tracker.drivers.spec import parse_driver_url

    gear = {"pan": settings.motor_gear_ratio_pan, "tilt": settings.motor_gear_ratio_tilt}
    return SerialMotorDriver(parse_driver_url(settings.driver), gear, guard_lines_rad(settings))


def driver_state(engine: Any) -> dict[str, Any]:
    """What the status shows about the driver: kind, address, link state, rates, round trips."""
    driver = getattr(engine, "driver", None)
    describe = getattr(driver, "describe", None)
    if callable(describe):
        out: dict[str, Any] = describe()
        return out
    return {"kind": "sim", "url": "sim", "state": "running"}


async def close_driver(engine: Any) -> None:
    """Stop and disconnect a PTZ camera or a serial rig (nothing to do for the simulated rig)."""
    close = getattr(getattr(engine, "driver", None), "close", None)
    if close is not None:
        done = close()
        if inspect.isawaitable(done):
            await done


def check_settings(settings: Settings) -> None:
    """Fail early (ConfigError, one line on the command line) on a bad effect plug-in, rig or
    array file. The site's effects load first: the rig file may hide one of them."""
    from tracker.plant.effects import load_effect_modules

    load_effect_modules(settings.effects, "effects setting")
    if settings.rig_config is not None:
        from tracker.drivers.sim import load_rig_config

        load_rig_config(settings.rig_config)
    if settings.array_file is not None or settings.audio_channel_map is not None:
        from app.audio import load_meeting_array

        array = load_meeting_array(settings.array_file)
        try:
            capture_settings(settings).mics_to_channels(array.n_mics)
        except ConfigError as exc:
            raise ConfigError(f"setting 'audio_channel_map': {exc}") from None


def build_engine(settings: Settings) -> Any:
    """The engine on the configured driver, with the service's phase-margin floor; with
    ``loop_process`` (the twin) the engine in a process of its own behind a
    :class:`tracker.loop_process.proxy.LoopProcess` with the same surface."""
    if settings.loop_process:
        from tracker.drivers.spec import parse_driver_url

        kind = parse_driver_url(settings.driver).kind
        if kind == "sim":
            from tracker.loop_process.proxy import LoopProcess

            return LoopProcess(build_local_engine, settings)
        log.warning("loop_process: the %s driver stays in the service's process (the twin only)", kind)
    return build_local_engine(settings)


def build_local_engine(settings: Settings) -> Any:
    """The engine on the configured driver in this process (the loop's process calls it too)."""
    from tracker.engine import Engine, EngineConfig

    config = EngineConfig(min_phase_margin_deg=settings.min_phase_margin_deg,
                          guard_margin_rad=math.radians(settings.guard_margin_deg),
                          chunk_s=settings.control_chunk_ms / 1e3,
                          loop_priority=settings.control_loop_priority)
    return Engine(build_live_driver(settings), config)


def build_live_driver(settings: Settings) -> Any:
    """What the engine steers: the PTZ camera or serial rig ``settings.driver`` names, or the
    simulated rig."""
    from tracker.drivers.spec import parse_driver_url

    kind = parse_driver_url(settings.driver).kind
    if kind == "visca":
        return build_camera(settings)
    if kind == "serial":
        return build_serial_rig(settings)
    return build_driver(settings)


def soft_limit_rad(engine: Any, axis: str) -> float:
    """The ± soft limit of ``axis`` (rad)."""
    from tracker.control.limits import SoftLimits

    return SoftLimits.for_axis(axis).upper_rad


def axis_model(engine: Any, axis: str) -> Any:
    """The plant model the engine designed ``axis``' controller on."""
    from tracker.plant.model import AxisModel

    if hasattr(engine, "model"):
        return engine.model(axis)
    models = getattr(getattr(engine, "config", None), "models", None) or {}
    return models.get(axis) or AxisModel.for_axis(axis)


def check_angle(axis: str, angle_deg: float, limit_deg: float) -> None:
    """Raise ConfigError (→ 422) naming the limit when ``angle_deg`` is outside ±limit."""
    if not math.isfinite(angle_deg) or abs(angle_deg) > limit_deg + 1e-9:
        raise ConfigError(f"{axis} angle {angle_deg:g}° is outside the soft limit ±{limit_deg:g}°")


def random_practice_model(axis: str, seed: int) -> Any:
    """The seed's model of ``axis`` with one effect, picked by ``seed``, at random physical values."""
    from tracker.workbench.experiments.experiments import HIDDEN_RANGES, random_hidden_model

    names = sorted(HIDDEN_RANGES)
    effect = names[int(np.random.default_rng(seed).integers(len(names)))]
    return random_hidden_model(axis, [effect], seed)


def attach_audio(engine: Any, settings: Settings, policy: Any = None) -> tuple[Any, str | None]:
    """Wire the simulated room's talker tracker in as the engine's target source, framing
    talkers with the camera-operator ``policy`` (a CameraPolicy; the defaults when None).

    Returns (handle, note); the handle is None and the note says why when audio is unavailable.
    """
    from app.audio import start_meeting_source

    try:
        source = start_meeting_source(engine, settings.data_dir, audio_input=settings.audio_input,
                                      array_file=settings.array_file, policy=policy,
                                      capture=capture_settings(settings))
    except ImportError as exc:  # audio stack missing: manual pointing still works
        return None, f"audio unavailable: {exc}"
    return source, None


def capture_settings(settings: Settings) -> Any:
    """How live capture opens the sound card (``audio_input = "live[:DEVICE]"``, the device's
    rate and channel map): a CaptureSettings."""
    from app.settings import parse_audio_input
    from tracker.audio.capture import CaptureSettings

    kind, device = parse_audio_input(settings.audio_input)
    dev: int | str | None = int(device) if device is not None and device.isdigit() else device
    channel_map = settings.audio_channel_map
    return CaptureSettings(device=dev if kind == "live" else None,
                           device_rate_hz=settings.audio_device_rate_hz,
                           channel_map=tuple(channel_map) if channel_map is not None else None)


async def detach_audio(handle: Any) -> None:
    close = getattr(handle, "close", None)
    if close is not None:
        close()
