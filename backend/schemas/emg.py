"""Request and response bodies of muscle activity: montages, EMG analysis settings, EMG
stream subscriptions, recordings and MVC steps (rows in `backend.db.emg`)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.lsl.names import LSL_TEXT_PATTERN
from backend.schemas.fields import UtcDatetime
from controller.emg.processing import allowed_ranges

MuscleId = Literal["erector_spinae_lumbar", "erector_spinae_thoracic", "gluteus_maximus",
                   "biceps_femoris", "rectus_abdominis", "rectus_femoris"]
SideName = Literal["left", "right"]


class MontageChannelIn(BaseModel):
    """One channel: its label in the recording, the muscle and side, and the electrodes."""

    model_config = ConfigDict(extra="forbid")
    label: str = Field(min_length=1, max_length=100)
    muscle: MuscleId
    side: SideName
    placement: str = Field(default="", max_length=500, description=(
        "where the electrodes sit, e.g. the SENIAM recommendation followed"))
    electrode_type: str = Field(default="", max_length=200)
    inter_electrode_distance_mm: float | None = Field(default=None, gt=0, le=100)
    reference: str = Field(default="", max_length=200)


class MontageIn(BaseModel):
    """A study's montage: each channel label and each (muscle, side) at most once."""

    model_config = ConfigDict(extra="forbid")
    placement_scheme: str = Field(default="SENIAM", max_length=200, description=(
        "the placement scheme followed (BIDS-EMG's EMGPlacementScheme)"))
    channels: list[MontageChannelIn] = Field(min_length=1, max_length=64)


class MontageOut(MontageIn):
    """One stored version of a study's montage."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    study_id: int
    version: int
    created_at: UtcDatetime


class EmgSettingsIn(BaseModel):
    """A study's EMG processing chain and normalisation (every parameter; missing ones
    take the defaults: DC removal, 20-450 Hz zero-phase band-pass, no notch, full-wave
    rectification, 6 Hz envelope, MVC normalisation)."""

    model_config = ConfigDict(extra="forbid")
    processing: dict[str, Any] = Field(default_factory=dict, description=(
        "controller.emg.processing.EmgProcessing in its dict form; remove_dc a boolean, "
        "notch_hz null, 50 or 60, orders integers 1-8; allowed ranges: "
        + allowed_ranges()))
    normalisation: Literal["mvc", "task_peak", "task_mean", "none"] | None = Field(
        default=None, description="the normalisation method (overrides processing's)")
    mains_hz: Literal[50, 60] = 50


class EmgSettingsOut(BaseModel):
    """The stored settings, complete (defaults filled in)."""

    processing: dict[str, Any]
    normalisation: str
    mains_hz: int


class EmgStreamIn(BaseModel):
    """Record an LSL stream of type EMG with the session."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1, max_length=200, pattern=LSL_TEXT_PATTERN)
    source_id: str = Field(default="", max_length=200, pattern=LSL_TEXT_PATTERN)
    ignore_labels: list[str] = Field(default_factory=list, max_length=64, description=(
        "stream channels to leave out on purpose (spare inputs with no electrode)"))


class EmgStreamOut(BaseModel):
    """A session's EMG stream subscription."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    name: str
    source_id: str
    montage_id: int
    ignored_labels: list[str]
    active: bool
    error: str
    created_at: UtcDatetime
    connected: bool = False
    #: The newest sample recorded so far, on the session clock (LSL time).
    last_time: float | None = None


class EmgRecordingOut(BaseModel):
    """One recording: source, span on the session clock, trials covered, quality."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    montage_id: int
    montage_version: int
    source: str
    status: str
    filename: str
    fs: float
    channel_count: int
    labels: list[str]
    n_samples: int
    time_offset_s: float
    alignment: str
    t_start: float | None
    t_end: float | None
    trials: list[dict[str, Any]]
    size_bytes: int
    sha256: str
    quality: dict[str, Any]
    created_at: UtcDatetime


class MvcStepIn(BaseModel):
    """One MVC step: a muscle, the side(s), repetitions, contraction and rest times."""

    model_config = ConfigDict(extra="forbid")
    muscle: MuscleId
    side: Literal["left", "right", "both"] = "both"
    repetitions: int = Field(default=3, ge=1, le=10)
    contraction_s: float = Field(default=5.0, gt=0, le=30)
    rest_s: float = Field(default=60.0, ge=0, le=600)


class MvcPlanIn(BaseModel):
    """A session's MVC steps, in order (replaces the steps none of whose repetitions ran)."""

    model_config = ConfigDict(extra="forbid")
    steps: list[MvcStepIn] = Field(min_length=1, max_length=24)


class MvcStepOut(MvcStepIn):
    """A stored MVC step with the repetitions done (their start and stop markers)."""

    model_config = ConfigDict(from_attributes=True, extra="ignore")
    id: int
    session_id: int
    planned_order: int
    repetitions_done: list[dict[str, Any]]


class MvcEventIn(BaseModel):
    """Start or stop the next repetition of an MVC step."""

    model_config = ConfigDict(extra="forbid")
    event: Literal["start", "stop"]


class TrialEmgChannel(BaseModel):
    """One channel's envelope over a trial, decimated for display."""

    label: str
    muscle: str
    side: str
    values: list[float] = Field(description="envelope in volts at the times `t`")
    flags: list[str] = Field(description="the recording's quality flags of this channel")


class TrialEmgLift(BaseModel):
    """One lift of the trial and its outcomes from the full-rate envelope, per channel."""

    index: int
    kind: str
    start_s: float = Field(description="from the trial's start")
    end_s: float
    peak: list[float] = Field(description="per channel; empty when not measured (flags)")
    mean: list[float]
    iemg: list[float] = Field(description="envelope integral over the lift, V s")
    flags: list[str] = Field(default_factory=list, description=(
        "no_emg:<coverage> (the recording holds under 90 % of the lift's samples: not "
        "measured) or samples_missing:<share>"))


class TrialEmgOut(BaseModel):
    """`GET /api/trials/{id}/emg-envelope`: the stored EMG's envelope over the trial."""

    trial_id: int
    recording_id: int
    source: str
    unit: Literal["V"] = "V"
    normalisation: Literal["none"] = Field(default="none", description=(
        "not normalised: the panel shows volts, results normalise per the study"))
    processing: dict[str, Any] = Field(description="the chain used (the study's settings)")
    recording_fs: float
    fs: float = Field(description="rate of the decimated values (Hz)")
    t: list[float] = Field(description="seconds from the trial's start")
    duration_s: float
    channels: list[TrialEmgChannel]
    lifts: list[TrialEmgLift]
    lift_source: str = Field(description="simulation, segments, task or none")
    lift_note: str
    flags: list[str] = Field(default_factory=list, description=(
        "the recording's flags concerning the whole trial (stream_lost, "
        "stopped_mid_trial, ...)"))
