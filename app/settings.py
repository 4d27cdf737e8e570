"""Service settings in one place: embedded defaults, then a TOML config file, then TRACKER_* variables.

Precedence (highest first): values passed in code, environment variables with the ``TRACKER_``
prefix (``TRACKER_PORT=9000``, ``TRACKER_VIEWER_ENABLED=false``), the TOML file named by
``--config`` or ``TRACKER_CONFIG``, the defaults below. The defaults run a working console with
nothing else installed: the simulated room and rig, SQLite in ``./data``.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, ValidationInfo, field_validator
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from tracker.errors import ConfigError

ENV_PREFIX = "TRACKER_"


class Settings(BaseSettings):
    """Everything the service reads at start-up."""

    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, extra="forbid", frozen=True)

    host: str = Field("127.0.0.1", description="address the console binds to")
    port: int = Field(8000, ge=0, le=65535, description="console port (0 picks a free one)")
    data_dir: Path = Field(Path("data"), description="SQLite database and the first admin key")
    realtime: bool = Field(True, description="run the engine at wall-clock pace")

    driver: str = Field(
        "sim",
        description="what the engine steers: 'sim' (the simulated rig), 'visca+udp://HOST[:52381]' "
        "(Sony VISCA over IP), 'visca+tcp://HOST:PORT' (raw VISCA, e.g. PTZOptics on 5678) or "
        "'serial:///dev/ttyUSB0[?baud=115200&rate=HZ&watchdog_ms=100]' (a DC rig's motor controller "
        "board: docs/serial-protocol.md)",
    )
    motor_gear_ratio_pan: float = Field(
        17.01, gt=0.0, le=10_000.0,
        description="serial rig: motor revolutions per pan revolution (the seed's 6.3:1 gear x 2.7:1 "
                    "pulley); the board's counts per motor revolution come from its hello")
    motor_gear_ratio_tilt: float = Field(
        17.01, gt=0.0, le=10_000.0, description="serial rig: motor revolutions per tilt revolution")
    camera_profile: str = Field(
        "generic", description="PTZ camera profile (tracker/drivers/camera_profiles.toml): "
        "generic, sony_srg, sony_evi_d70, ptzoptics")
    camera_rate_hz: float = Field(25.0, ge=5.0, le=50.0, description="commands per second to a PTZ camera")
    camera_steering: Literal["speed", "position"] = Field(
        "speed", description="steer a PTZ camera with speed drives (default) or absolute positions")
    rig_config: Path | None = Field(
        None, description="JSON of hidden effects for the simulated rig (tracker/drivers/sim.py)"
    )
    effects: str = Field(
        "",
        description="a site's own effects: modules or .py files defining EFFECT, comma-separated "
        "(docs/workbench.md, 'Your own effect'); the engine also reads TRACKER_EFFECTS itself",
    )
    audio_enabled: bool = Field(True, description="use the simulated room as the tracking target source")
    track_on_start: bool = Field(
        True, description="a fresh start follows the talker (tracking on once the target source is "
        "attached; a stored tracking on/off, PUT /tracking, wins)"
    )
    array_file: Path | None = Field(
        None, description="microphone array JSON; default: the shipped 4-mic square"
    )
    audio_input: str = Field(
        "simulated",
        description="what the talker tracker listens to: 'simulated' (the meeting room), "
        "'live' or 'live:DEVICE' (sound card through PortAudio), 'wav:PATH' (a multichannel file)",
    )
    audio_device_rate_hz: int | None = Field(
        None, ge=8000, le=384000,
        description="live capture: open the sound card at this rate (16000, 44100, 48000 ...; "
        "resampled to the localizer's 16 kHz); default: the device's own default rate")
    audio_channel_map: list[int] | None = Field(
        None, description="live capture: the device channel (from 0) of each array microphone, "
        "in the array file's order, e.g. [2, 3, 4, 5]; default: the first n_mics channels")
    camera_policy: dict[str, float] = Field(
        default_factory=dict,
        description="the camera operator's policy for this room (docs/audio.md, 'The camera "
        "operator'): reaction_time_s, min_hold_s, pause_tolerance_s, deadband_deg, "
        "wide_after_switches, wide_window_s, wide_release_s, lead_s; a [camera_policy] table in "
        "the config file or TRACKER_CAMERA_POLICY as JSON; values an engineer stores through the "
        "API take precedence")

    viewer_enabled: bool = Field(True, description="start the viser 3D view")
    viewer_host: str = Field("127.0.0.1", description="viser binds here; it has no authentication")
    viewer_port: int = Field(8081, ge=0, le=65535)
    viewer_rate_hz: float = Field(30.0, gt=0, le=120)

    control_chunk_ms: float = Field(
        10.0, ge=1.0, le=50.0,
        description="the control loop's tick: each tick runs this many ms of 1 kHz samples (10: 100 "
                    "ticks a second; 1: one sample a tick) and publishes one telemetry snapshot")
    control_loop_priority: int = Field(
        0, ge=0, le=99,
        description="SCHED_FIFO priority of the control loop's thread on Linux (0: normal scheduling); "
                    "needs CAP_SYS_NICE (systemd: CPUSchedulingPolicy/LimitRTPRIO), ignored if refused")
    loop_process: bool = Field(
        False,
        description="run the control loop and the simulated rig in a process of their own (a "
                    "spawned child at control_loop_priority whose only Python thread is the loop; "
                    "calls over a pipe, telemetry and status in shared memory), so no thread of "
                    "the service can hold up a tick (docs/console.md); driver = 'sim' only, a "
                    "camera or serial rig stays in the service's process")
    service_threads_priority: int = Field(
        0, ge=0, le=98,
        description="SCHED_FIFO priority of the service's other threads (web, telemetry; 0: normal "
                    "scheduling), below control_loop_priority: a thread holding the interpreter lock "
                    "is then not preempted by other processes, which would hold up the loop's tick "
                    "(docs/console.md); worker processes still run in the normal class; ignored if "
                    "refused")
    telemetry_rate_hz: float = Field(100.0, ge=50.0, le=1000.0, description="WebSocket frame rate")
    jog_timeout_s: float = Field(0.5, gt=0.0, le=5.0, description="a jog stops by itself after this")
    control_lock_ttl_s: float = Field(30.0, gt=0.0, description="manual control lapses when idle this long")
    min_phase_margin_deg: float = Field(45.0, ge=0.0, le=90.0, description="gains under this are refused")
    guard_margin_deg: float = Field(
        0.25, ge=0.0, le=40.0,
        description="the soft-limit guard's line sits this far inside the limits (a belt the model "
                    "does not know needs its twist at full torque: docs/control.md)")
    # Limits: what one request may cost the service (docs/console.md, "Limits").
    max_body_bytes: int = Field(
        65_536, gt=0, description="a JSON request body over this is refused (413) before it is read; "
        "the largest the API takes is a few kB, and an invalid one costs the event loop ~1 ms per kB")
    max_upload_bytes: int = Field(
        20_000_000, gt=0, description="a measurement upload over this is refused (413) before it is read")
    max_measurement_rows: int = Field(
        250_000, gt=0, description="a measurement with more data rows is refused (413): 250 s at 1 kHz")
    heavy_workers: int = Field(
        1, ge=1, le=32, description="worker processes for heavy work (workbench, simulations)")
    heavy_queue: int = Field(
        4, ge=0, le=1000, description="heavy requests that may wait for a worker; more get 429")
    heavy_per_key: int = Field(
        2, ge=1, le=100, description="heavy requests one key may have running or waiting; more get 429")
    max_running_jobs: int = Field(2, ge=1, le=32, description="jobs (friction-ID) at once; more get 429")
    bad_key_limit: int = Field(
        10, ge=1, description="bad keys one address may send within bad_key_window_s before 429")
    bad_key_window_s: float = Field(60.0, gt=0.0)
    bad_key_max_block_s: float = Field(
        600.0, ge=1.0, description="each block doubles from 5 s up to this while the bad keys go on")
    job_workers: int = Field(
        1, ge=1, le=8, description="worker processes for jobs (friction-ID), with progress and cancel; "
                                   "they never share the control loop's interpreter")
    # Operations (docs/operations.md).
    metrics_role: Literal["public", "viewer", "operator", "engineer", "admin"] = Field(
        "viewer", description="the role a key needs to read /metrics (X-API-Key or Authorization: Bearer); "
        "'public': no key (only behind a firewall: the figures tell when the room is in use)")
    health_stall_s: float = Field(
        2.0, gt=0.0, le=600.0, description="/health answers 503 when the control loop has not "
        "ticked for longer than this")
    audit_max_rows: int = Field(100_000, ge=100, description="the audit log keeps this many newest entries")
    log_level: Literal["debug", "info", "warning", "error"] = "info"

    @field_validator("service_threads_priority")
    @classmethod
    def _check_service_threads_priority(cls, value: int, info: ValidationInfo) -> int:
        loop = info.data.get("control_loop_priority", 0)  # declared before: validated first
        if value > 0 and not value < loop:
            raise ValueError(f"{value} must be below control_loop_priority ({loop}): the loop's "
                             "thread must come first")
        return value

    @field_validator("audio_input")
    @classmethod
    def _check_audio_input(cls, value: str) -> str:
        parse_audio_input(value)
        return value

    @field_validator("audio_channel_map")
    @classmethod
    def _check_channel_map(cls, value: list[int] | None) -> list[int] | None:
        from tracker.audio.capture import CaptureSettings

        if value is not None:
            try:
                CaptureSettings(channel_map=tuple(value))
            except ConfigError as exc:
                raise ValueError(str(exc)) from None
        return value

    @field_validator("camera_policy")
    @classmethod
    def _check_camera_policy(cls, value: dict[str, float]) -> dict[str, float]:
        from app.policy import policy_from_json

        try:
            policy_from_json(value, where="camera_policy")
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
        return value

    @field_validator("driver")
    @classmethod
    def _check_driver(cls, value: str) -> str:
        from tracker.drivers.spec import parse_driver_url

        try:
            return parse_driver_url(value).url
        except ConfigError as exc:
            raise ValueError(str(exc)) from None

    @field_validator("camera_profile")
    @classmethod
    def _check_camera_profile(cls, value: str) -> str:
        from tracker.drivers.camera_profiles import get_profile

        try:
            get_profile(value)
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
        return value

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        return (init_settings, env_settings, _FileSource(settings_cls))

    @property
    def db_path(self) -> Path:
        """The SQLite database file."""
        return self.data_dir / "console.sqlite3"

    @property
    def admin_key_path(self) -> Path:
        """Where the first start writes the admin key (mode 0600)."""
        return self.data_dir / "admin.key"


def parse_audio_input(value: str) -> tuple[str, str | None]:
    """``audio_input`` as (kind, argument): ("simulated", None), ("live", device or None), ("wav", path).

    Raises ValueError (reported by :func:`load_settings` as a ConfigError naming the setting).
    """
    kind, _, arg = value.strip().partition(":")
    kind = kind.lower()
    if kind == "simulated" and not arg:
        return kind, None
    if kind == "live":
        return kind, arg or None
    if kind == "wav":
        if not arg:
            raise ValueError("'wav:' needs a file path, e.g. wav:/data/meeting.wav")
        if not Path(arg).is_file():
            raise ValueError(f"WAV file {arg!r} not found")
        return kind, arg
    raise ValueError(f"{value!r} is not one of simulated, live, live:DEVICE, wav:PATH")


class _FileSource(PydanticBaseSettingsSource):
    """Values from the TOML file in ``_FILE_VALUES`` (set by :func:`load_settings`)."""

    values: dict[str, Any] = {}

    def get_field_value(self, field: Any, field_name: str) -> tuple[Any, str, bool]:
        return self.values.get(field_name), field_name, False

    def __call__(self) -> dict[str, Any]:
        return dict(self.values)


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Read a TOML config file; keys are settings names (a ``[tracker]`` table is also accepted)."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file {p}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"config file {p}: cannot read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config file {p}: {exc}") from None
    if isinstance(data.get("tracker"), dict):
        data = data["tracker"]
    return data


def load_settings(config: str | Path | None = None, **overrides: Any) -> Settings:
    """Settings from defaults, the config file (``config`` or TRACKER_CONFIG), env and ``overrides``.

    Raises ConfigError naming the bad setting and where it came from.
    """
    path = config or os.environ.get(f"{ENV_PREFIX}CONFIG")
    file_values = read_config_file(path) if path else {}
    overrides = {k: v for k, v in overrides.items() if v is not None}
    _FileSource.values = file_values
    try:
        return Settings(**overrides)
    except ValidationError as exc:
        first = exc.errors()[0]
        name = ".".join(str(x) for x in first["loc"])
        where = f"config file {path}" if name in file_values else f"environment {ENV_PREFIX}{name.upper()}"
        if name in overrides:
            where = "command line"
        raise ConfigError(f"setting {name!r} ({where}): {first['msg']}") from None
    finally:
        _FileSource.values = {}
