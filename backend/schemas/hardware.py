"""Hardware bring-up over HTTP: the step requests, their results and the stored profile
(`backend/study/hardware_profiles.py`, docs/hardware-bringup.md)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.schemas.fields import UtcDatetime

Side = Literal["left", "right"]
STEP_NAMES: tuple[str, ...] = ("zero", "direction_left", "direction_right", "offset",
                               "pulse_left", "pulse_right", "watchdog", "link")


class CaptureIn(BaseModel):
    """A capture with the solenoids off: zero (standing still) or offset (unlocked)."""

    model_config = ConfigDict(extra="forbid")
    seconds: float = Field(default=2.0, ge=0.5, le=10.0,
                           description="how long to average, s")


class DirectionIn(BaseModel):
    """The direction step of one side: the experimenter flexes that hip meanwhile."""

    model_config = ConfigDict(extra="forbid")
    side: Side
    seconds: float = Field(default=4.0, ge=1.0, le=10.0,
                           description="capture window in which the hip flexes, s")


class PulseIn(BaseModel):
    """A solenoid test pulse. `nobody_wearing` must be true: the experimenter confirms
    that nobody wears the exoskeleton (a pulse under load could lock a side)."""

    model_config = ConfigDict(extra="forbid")
    side: Side
    duration_ms: float = Field(default=300.0, ge=10.0, le=300.0,
                               description="pulse length, at most the 0.3 s lock hold")
    nobody_wearing: bool = False


class WatchdogIn(BaseModel):
    """The watchdog test on one side; `nobody_wearing` as for the pulse."""

    model_config = ConfigDict(extra="forbid")
    side: Side = "left"
    nobody_wearing: bool = False


class FinishIn(BaseModel):
    """Close the draft profile. `firmware_version`: what real firmware reports (its
    boot banner or label); ignored for the simulators, whose version is known."""

    model_config = ConfigDict(extra="forbid")
    firmware_version: str | None = Field(default=None, max_length=200)


class StepOut(BaseModel):
    """One step's verdict as stored in the profile."""

    passed: bool
    message: str
    at: UtcDatetime
    values: dict[str, Any] = Field(default_factory=dict)


class ProfileOut(BaseModel):
    """A hardware profile (a draft while its steps run)."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    status: str
    device: str
    firmware_version: str
    key_id: str
    precompression_pct: float
    encoder_offsets: list[int]
    encoder_directions: list[int]
    cam_output_offsets: list[int]
    steps: dict[str, StepOut]
    created_at: UtcDatetime
    completed_at: UtcDatetime | None
    created_by: int | None


class StepResultOut(BaseModel):
    """The answer to a step: its verdict and the draft profile it was stored in."""

    step: str
    result: StepOut
    profile: ProfileOut


class HardwareStateOut(BaseModel):
    """What the bring-up page shows: the draft, the profile in effect, the device."""

    device: str
    simulated: bool
    steps: list[str]
    draft: ProfileOut | None
    active: ProfileOut | None
    #: The encoder layout the worker decodes counts with now (offsets, directions).
    applied_offsets: list[int]
    applied_directions: list[int]
    #: Why the applied layout is not the active profile's (simulators), else "".
    applied_note: str
