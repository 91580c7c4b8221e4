"""Hardware bring-up over HTTP: the step requests, their results and the stored profile
(`backend/study/hardware_profiles.py`, docs/hardware-bringup.md)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

from backend.schemas.fields import UtcDatetime

Side = Literal["left", "right"]
STEP_NAMES: tuple[str, ...] = ("zero", "direction_left", "direction_right", "offset",
                               "pulse_left", "pulse_right", "watchdog", "hardware_release",
                               "link")


def _json_bool(value: object) -> object:
    """Only JSON true or false: a safety confirmation is never read from "yes", "on",
    "1", 1 or 1.0 (pydantic's lax mode would take them all)."""
    if isinstance(value, bool):
        return value
    raise ValueError(f"must be JSON true or false, not {value!r}: a safety confirmation "
                     "is never guessed from a string or a number")


#: A boolean that confirms something about a person's safety: JSON true/false only.
SafetyBool = Annotated[bool, BeforeValidator(_json_bool)]


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
    nobody_wearing: SafetyBool = False


class WatchdogIn(BaseModel):
    """The watchdog test on one side; `nobody_wearing` as for the pulse."""

    model_config = ConfigDict(extra="forbid")
    side: Side = "left"
    nobody_wearing: SafetyBool = False


class ReleaseIn(BaseModel):
    """The hardware release test on one side (the heartbeat monitor cuts the drivers);
    `nobody_wearing` as for the pulse."""

    model_config = ConfigDict(extra="forbid")
    side: Side = "left"
    nobody_wearing: SafetyBool = False


class FinishIn(BaseModel):
    """Close the draft profile. `firmware_version`: only for a device that reports no
    firmware in its CHALLENGE (what its boot banner or label says); a reported one
    always wins."""

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
    unique_id: str = Field(description="the unique id the device reported (32 hex)")
    precompression_pct: float
    encoder_offsets: list[int]
    encoder_directions: list[int]
    cam_output_offsets: list[int]
    steps: dict[str, StepOut]
    created_at: UtcDatetime
    completed_at: UtcDatetime | None
    expires_at: UtcDatetime | None = Field(
        default=None, description="a draft is closed as `expired` at this time")
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
    #: Why the applied layout is not the active profile's (simulators, another
    #: device on the link), else "".
    applied_note: str
    #: The device on the link as it proved itself (unique id, firmware, key id); ""
    #: before it did.
    identity: str = ""
    #: The active profile applies, but the device's firmware changed since ("" if not).
    firmware_notice: str = ""
    #: Seconds until each side's solenoid may be energised again (duty cycle).
    cooldown_s: dict[str, float] = Field(default_factory=dict)


class DeviceGrantOut(BaseModel):
    """An account's device grant (docs/access.md): it may pulse a solenoid, start a
    controller or a trial, and run the bring-up."""

    username: str
    granted_at: UtcDatetime
    granted_by: str | None = Field(description="the administrator who gave it")
