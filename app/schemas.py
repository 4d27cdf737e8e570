"""Request and response bodies of the REST API (pydantic; angles in degrees, rates in deg/s).

Request bodies are strict: numbers are finite JSON numbers (no NaN, Infinity or 1e999, no
``true`` for 1, no strings), ids fit SQLite's integers (1 .. 2⁶³−1), unknown fields are refused.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Path
from pydantic import BaseModel, ConfigDict, Field

Axis = Literal["pan", "tilt"]
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9 _.\-]{0,63}$"
MAX_ID = 2**63 - 1  # SQLite's largest integer

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Id = Annotated[int, Field(strict=True, ge=1, le=MAX_ID)]
RowId = Annotated[int, Path(ge=1, le=MAX_ID, description="a stored id (1 .. 2^63-1)")]
GainName = Annotated[str, Field(min_length=1, max_length=64)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class LoopOut(BaseModel):
    """How well the control loop keeps its clock since the engine started."""

    period_ms: float = Field(description="the tick period: one chunk of control samples")
    ticks: int
    last_lateness_ms: float = Field(description="how late the last tick started")
    max_lateness_ms: float = Field(description="the largest lateness since the warm-up (warm_up_ticks)")
    mean_lateness_ms: float = Field(description="the mean lateness since the warm-up")
    warm_up_ticks: int = Field(0, description="the loop's first ticks (its first second: the first "
                                              "chunk compiles or loads the numba kernels), left out "
                                              "of max_lateness_ms and mean_lateness_ms")
    warm_up_max_lateness_ms: float = Field(0.0, description="the largest lateness in the warm-up")
    overruns: int = Field(description="ticks that started a whole period (or more) late")
    restarts: int = Field(description="times the loop fell over 0.1 s behind and dropped ticks")
    in_thread: bool = Field(description="the loop runs in its own thread (real time)")
    priority: int = Field(0, description="the loop thread's SCHED_FIFO priority (0: normal scheduling)")
    service_threads_priority: int = Field(
        0, description="the SCHED_FIFO priority of the service's other threads (0: normal scheduling)")
    last_tick_ms_ago: float | None = Field(
        None, description="since the latest tick started (null before the first); /health says 503 "
                          "past health_stall_s")


class StatusOut(BaseModel):
    t_s: float
    pan_deg: float
    tilt_deg: float
    pan_target_deg: float
    tilt_target_deg: float
    mode: str
    tracking: bool
    active_talker: str | None
    faults: list[str]
    control_holder: dict[str, Any] | None = Field(None, description="who holds manual control")
    limits_deg: dict[str, float]
    telemetry_clients: int
    audio: str = Field("off", description="the simulated room's state as target source")
    audio_capture: dict[str, Any] | None = Field(
        None, description="live capture: state (running | fault | closed), device, device and "
        "pipeline rates, channel map, blocks, overflows, dropped blocks, faults, reconnects, fault, "
        "retry_in_s, resample_cpu_ms_per_s")
    talkers: list[dict[str, Any]] = Field(
        default_factory=list, description="the talkers the tracker has followed: talker_id, "
        "azimuth_deg, elevation_deg, speaking, last_spoken_ago_s, speaking_s")
    viewer: dict[str, Any] | None = None
    driver: dict[str, Any] = Field(
        default_factory=lambda: {"kind": "sim"},
        description="what the engine steers: kind (sim | visca), url, and for a camera its profile, link "
                    "state (connecting | connected | reconnecting), command rate, round trips, retransmits")
    loop: LoopOut | None = Field(None, description="the control loop's timing")
    settings_warnings: list[str] = Field(
        default_factory=list, description="stored settings not restored at start-up, and why (the "
                                          "defaults are in use; docs/operations.md)")


class TrackingIn(Strict):
    enabled: bool


class TrackingOut(BaseModel):
    tracking: bool
    mode: str


class PointingIn(Strict):
    pan_deg: Finite
    tilt_deg: Finite


class PointingOut(BaseModel):
    pan_target_deg: float
    tilt_target_deg: float
    mode: str
    control_holder: dict[str, Any] | None


class JogIn(Strict):
    rate_deg_s: Finite = Field(description="signed rate; 0 stops")


class JogOut(BaseModel):
    axis: Axis
    rate_deg_s: float
    auto_stop_s: float


class PresetIn(Strict):
    pan_deg: Finite | None = Field(None, description="default: where the camera points now")
    tilt_deg: Finite | None = None


class PresetOut(BaseModel):
    name: str
    pan_deg: float
    tilt_deg: float


class GainsOut(BaseModel):
    axis: Axis
    gains: dict[str, Any]
    margins: dict[str, Any]
    min_phase_margin_deg: float
    model_check: dict[str, Any] | None = Field(
        default=None, description="PUT /axes/{axis}/model: how the model predicted the axis's recent motion"
    )


class GainsIn(Strict):
    gains: dict[GainName, Finite] = Field(
        max_length=32, description="fields of the axis gain set to change (others kept)"
    )


class StepPreviewIn(Strict):
    gains: dict[GainName, Finite] = Field(default_factory=dict, max_length=32)
    amplitude_deg: Finite = Field(30.0, gt=0, le=180)
    duration_s: Finite = Field(1.5, gt=0, le=10)
    shaped: bool = Field(True, description="through the engine's rate/acceleration shaping (as on the rig)")


class DesignModelIn(Strict):
    version_id: Id = Field(description="a workbench model version of this axis")


class KeyIn(Strict):
    name: str = Field(pattern=NAME_PATTERN)
    role: Literal["viewer", "operator", "engineer", "admin"]


class KeyOut(BaseModel):
    id: int
    name: str
    role: str
    prefix: str
    revoked: bool
    key: str | None = Field(None, description="shown once, at creation; never stored")


class CompareIn(Strict):
    version_id: Id | None = None
    horizon_s: Finite | None = Field(None, gt=0, le=60)
    mode: Literal["k_step", "free"] = "k_step"


class DiagnoseIn(Strict):
    version_id: Id | None = None


class FitIn(Strict):
    version_id: Id | None = None
    free: list[Annotated[str, Field(min_length=1, max_length=64)]] | None = Field(None, max_length=64)


class AddEffectIn(Strict):
    effect: str = Field(min_length=1, max_length=64)
    version_id: Id | None = None


class FrictionJobIn(Strict):
    axis: Axis = "pan"
    source: Literal["rig", "practice", "live"] = Field(
        "rig", description="rig: a twin built like the live rig; practice: the practice rig; live: the "
                           "service's own DC rig (a serial motor controller), taken over for the sweep")
    voltages: int = Field(10, ge=3, le=30, description="constant-voltage runs per direction")


class SpeedIdJobIn(Strict):
    axis: Axis = "pan"
    count: int = Field(6, ge=2, le=32, description="speed steps spread over the profile's table")
    steps: list[int] | None = Field(None, min_length=1, max_length=32,
                                    description="the steps to measure instead of `count` (1..table size)")


class PracticeNewIn(Strict):
    axis: Axis = "pan"
    seed: int | None = Field(None, ge=0, le=2**32 - 1)


class ExperimentIn(Strict):
    kind: Literal["steps", "sine_sweep", "slow_ramps", "mixed"] = "mixed"
    duration_s: Finite = Field(20.0, ge=2.0, le=120.0)
