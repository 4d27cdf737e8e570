"""Request and response bodies of the REST API (pydantic; angles in degrees, rates in deg/s)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

Axis = Literal["pan", "tilt"]
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9 _.\-]{0,63}$"


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


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
    viewer: dict[str, Any] | None = None
    driver: dict[str, Any] = Field(
        default_factory=lambda: {"kind": "sim"},
        description="what the engine steers: kind (sim | visca), url, and for a camera its profile, link "
                    "state (connecting | connected | reconnecting), command rate, round trips, retransmits")


class TrackingIn(Strict):
    enabled: bool


class TrackingOut(BaseModel):
    tracking: bool
    mode: str


class PointingIn(Strict):
    pan_deg: float = Field(allow_inf_nan=False)
    tilt_deg: float = Field(allow_inf_nan=False)


class PointingOut(BaseModel):
    pan_target_deg: float
    tilt_target_deg: float
    mode: str
    control_holder: dict[str, Any] | None


class JogIn(Strict):
    rate_deg_s: float = Field(allow_inf_nan=False, description="signed rate; 0 stops")


class JogOut(BaseModel):
    axis: Axis
    rate_deg_s: float
    auto_stop_s: float


class PresetIn(Strict):
    pan_deg: float | None = Field(
        None, allow_inf_nan=False, description="default: where the camera points now"
    )
    tilt_deg: float | None = Field(None, allow_inf_nan=False)


class PresetOut(BaseModel):
    name: str
    pan_deg: float
    tilt_deg: float


class GainsOut(BaseModel):
    axis: Axis
    gains: dict[str, Any]
    margins: dict[str, Any]
    min_phase_margin_deg: float


class GainsIn(Strict):
    gains: dict[str, float] = Field(description="fields of the axis gain set to change (others kept)")


class StepPreviewIn(Strict):
    gains: dict[str, float] = Field(default_factory=dict)
    amplitude_deg: float = Field(30.0, gt=0, le=180, allow_inf_nan=False)
    duration_s: float = Field(1.5, gt=0, le=10, allow_inf_nan=False)
    shaped: bool = Field(True, description="through the engine's rate/acceleration shaping (as on the rig)")


class DesignModelIn(Strict):
    version_id: int = Field(description="a workbench model version of this axis")


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
    version_id: int | None = None
    horizon_s: float | None = Field(None, gt=0, le=60, allow_inf_nan=False)
    mode: Literal["k_step", "free"] = "k_step"


class DiagnoseIn(Strict):
    version_id: int | None = None


class FitIn(Strict):
    version_id: int | None = None
    free: list[str] | None = None


class AddEffectIn(Strict):
    effect: str = Field(min_length=1, max_length=64)
    version_id: int | None = None


class FrictionJobIn(Strict):
    axis: Axis = "pan"
    source: Literal["rig", "practice"] = "rig"


class PracticeNewIn(Strict):
    axis: Axis = "pan"
    seed: int | None = Field(None, ge=0)


class ExperimentIn(Strict):
    kind: Literal["steps", "sine_sweep", "slow_ramps", "mixed"] = "mixed"
    duration_s: float = Field(20.0, ge=2.0, le=120.0, allow_inf_nan=False)
