"""Request and response bodies for recordings, segments, model sets, utility sets, jobs
and trials (the ORM rows stay in `backend.db.evidence_tables`)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from backend.schemas.fields import MAX_ID, MIN_TIMED_S, UtcDatetime
from backend.schemas.live import SimulationChoice

SegmentLabel = Literal["squat", "stoop_left", "stoop_right", "other", "unlabelled"]


class RecordingIn(BaseModel):
    """Start a recording of demonstrations (the worker records with no locks)."""

    label: str = Field(default="", max_length=200)
    notes: str = Field(default="", max_length=5000)
    simulation: SimulationChoice | None = Field(default=None, description=(
        "in-process simulated device only: put this virtual participant and script on it "
        "as the recording starts, so that the recording holds the script from its first "
        "sample (a simulation faster than real time runs ahead while a recording is "
        "started by a second request)"))
    duration_s: float | None = Field(default=None, ge=MIN_TIMED_S, le=3600, description=(
        "with `simulation` only: the recording holds this much device time (seconds, "
        "rounded to whole 10 ms samples as a timed trial's, at least one) from the "
        "wearer's first sample; the worker ends it by itself, so a simulation faster "
        "than real time does not run on into a stop that comes late, and the simulated "
        "wearer goes on at real time from then"))


class RecordingOut(BaseModel):
    """A recording and where its ticks are."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    run_id: int | None
    label: str
    status: str
    started_at: UtcDatetime
    ended_at: UtcDatetime | None
    first_tick_id: int | None
    last_tick_id: int | None
    notes: str


class SegmentIn(BaseModel):
    """A lift as sample indices from the recording's first tick."""

    start: int = Field(ge=0, le=MAX_ID)
    peak: int = Field(ge=0, le=MAX_ID)
    end: int = Field(ge=0, le=MAX_ID)
    label: SegmentLabel = "unlabelled"

    @model_validator(mode="after")
    def _ordered(self) -> SegmentIn:
        if not self.start < self.peak < self.end:
            raise ValueError("indices must satisfy start < peak < end")
        return self


class SegmentUpdate(BaseModel):
    """Move a segment's edges or relabel it."""

    start: int | None = Field(default=None, ge=0, le=MAX_ID)
    peak: int | None = Field(default=None, ge=0, le=MAX_ID)
    end: int | None = Field(default=None, ge=0, le=MAX_ID)
    label: SegmentLabel | None = None


class SegmentOut(BaseModel):
    """A lift segment."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    recording_id: int
    start: int
    peak: int
    end: int
    label: str
    source: str
    updated_at: UtcDatetime


class TrialSegmentOut(BaseModel):
    """A lift the experimenter marked in a trial (sample indices from its first tick)."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    trial_id: int
    start: int
    peak: int
    end: int
    label: str
    source: str
    updated_at: UtcDatetime


class RecordingAngles(BaseModel):
    """A recording's hip angles, for plotting it with its segments."""

    t: list[float]
    q_left: list[float | None]
    q_right: list[float | None]
    truth_activity: list[str]


class ModelSetIn(BaseModel):
    """Fit a model set from labelled segments (a background job)."""

    name: str = Field(min_length=1, max_length=200)
    segment_ids: list[Annotated[int, Field(ge=1, le=MAX_ID)]] = Field(min_length=6,
                                                                        max_length=10_000)
    latent_dim: int | None = Field(default=None, ge=1, le=200)
    explained_variance: float = Field(default=0.95, gt=0.0, lt=1.0)


class ModelSetOut(BaseModel):
    """A model set; `document` is the full versioned JSON once fitted."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    study_id: int
    name: str
    status: str
    params: dict[str, Any]
    segment_ids: list[int]
    error: str
    created_at: UtcDatetime
    job_id: int | None = None
    #: population or personal; ppca (fitted) or map (a population set adapted).
    kind: str = "population"
    method: str = "ppca"
    #: A personal set's wearer and the population set it adapts.
    participant_id: int | None = None
    base_model_set_id: int | None = None


class UtilitySetIn(BaseModel):
    """Compute utilities for a precompression from the built-in simulated human dataset
    (`human_source="simulated"`) or an imported one (upload CSV first)."""

    name: str = Field(min_length=1, max_length=200)
    precompression_pct: float = Field(ge=0.0, le=100.0)


class UtilitySetOut(BaseModel):
    """A utility set."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    study_id: int
    name: str
    precompression_pct: float
    human_source: str
    status: str
    error: str
    created_at: UtcDatetime
    job_id: int | None = None


class UtilityCurves(BaseModel):
    """Utility of each action minus that of "no lock", per motion, over progress (the
    paper's utility figure)."""

    progress: list[float]
    differences: dict[str, dict[str, list[float]]]
    other: dict[str, float]


class JobOut(BaseModel):
    """A background job: a model fit (`fit_model_set`), a utility table
    (`compute_utilities`) or a virtual cohort (`cohort`), of the model set, utility set
    or cohort `target_id`. `status` is queued, running, then done (succeeded), failed
    or cancelled; `message` says what it produced, or why it failed or was cancelled
    (e.g. "interrupted by a server restart at ...")."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    kind: str
    target_id: int
    status: Literal["queued", "running", "done", "failed", "cancelled"]
    #: The runner thread it waits for: `study` (short jobs) or `cohort`.
    lane: str
    progress: float
    message: str
    created_at: UtcDatetime
    started_at: UtcDatetime | None
    finished_at: UtcDatetime | None


PlanVariant = Literal["population", "personal", "population+priors", "personal+priors"]


class DemonstrationCounts(BaseModel):
    """Demonstrations of each motion asked for in a demonstration block."""

    model_config = ConfigDict(extra="forbid")
    squat: int = Field(ge=1, le=50)
    stoop_left: int = Field(ge=1, le=50)
    stoop_right: int = Field(ge=1, le=50)


class TrialPlanIn(BaseModel):
    """Plan an evaluation session's trials in the study's counterbalanced order."""

    tasks: list[str] = Field(default_factory=lambda: ["squat-sequence", "stoop-sequence",
                                                      "walking", "stairs"],
                             min_length=1, max_length=20)
    include_eumc: bool = Field(default=True, description=(
        "plan the controllers registered as optional in a plan too (the E-UMC)"))
    include_baselines: bool = Field(default=False, description=(
        "plan the baseline conditions too (springs free, no exoskeleton), counterbalanced "
        "and blinded with the controllers; for the plan's lift tasks only (a task with "
        "squat, stoop or lift in its name) unless `baseline_tasks` names them"))
    baseline_tasks: list[Annotated[str, Field(min_length=1, max_length=100)]] | None = Field(
        default=None, min_length=1, max_length=20, description=(
            "the tasks the baselines are planned for (with include_baselines); default: "
            "the plan's lift tasks"))
    # Ids within what the id columns hold: a larger one is a 422, not a driver overflow.
    model_set_id: int | None = Field(default=None, ge=1, le=MAX_ID)
    utility_set_id: int | None = Field(default=None, ge=1, le=MAX_ID)
    replace: bool = Field(default=False, description=(
        "replace the session's plan, allowed while none of its trials has started "
        "(a plan with a started trial is kept, with its data)"))
    conditions: list[PlanVariant] = Field(
        default_factory=lambda: list[PlanVariant](["population"]), min_length=1,
        max_length=4, description=(
            "the variants of every controller with motion models, each a blinded, "
            "counterbalanced condition: population or personal models, with equal or "
            "the prior set's priors (the PEC and baselines run once)"))
    personal_model_set_id: int | None = Field(default=None, ge=1, le=MAX_ID, description=(
        "the participant's personal model set for the personal conditions; if unset, "
        "their newest ready personal set when each such trial starts (fit it from the "
        "demonstration block first)"))
    prior_set_id: int | None = Field(default=None, ge=1, le=MAX_ID, description=(
        "the participant's prior set for the +priors conditions"))
    demonstrations: DemonstrationCounts | None = Field(default=None, description=(
        "a demonstration block first in the plan (no locks): how many of each motion"))

    @model_validator(mode="after")
    def _conditions_distinct(self) -> TrialPlanIn:
        if len(set(self.conditions)) != len(self.conditions):
            raise ValueError(f"conditions: each at most once, got {self.conditions}")
        if self.baseline_tasks is not None and not self.include_baselines:
            raise ValueError("baseline_tasks: given without include_baselines: true")
        return self


class TrialStartIn(BaseModel):
    """Options for starting a trial."""

    rate_hz: float | None = Field(default=None, gt=0.0, le=100.0,
                                  description="every controller at this rate; paper's if unset")
    duration_s: float | None = Field(default=None, ge=MIN_TIMED_S, le=24 * 3600.0, description=(
        "a timed trial: the worker ends the controller after this much device time "
        "(rounded to whole 10 ms samples, at least one), so the trial holds exactly "
        "that; stop it as usual. A "
        "simulated wearer faster than real time goes on at real time from then"))
    simulation: SimulationChoice | None = Field(default=None, description=(
        "in-process simulated device only: put this virtual participant and script on it "
        "as the trial starts, so that the trial holds the script from its first sample "
        "(the same data at any speed, however long the request took)"))


class TrialStopIn(BaseModel):
    """End a trial."""

    outcome: Literal["completed", "aborted"] = "completed"
    reason: str = Field(default="", max_length=2000)


class TrialOut(BaseModel):
    """A trial and the exact configuration it ran with."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    controller: str
    task: str
    planned_order: int
    status: str
    model_set_id: int | None
    utility_set_id: int | None
    run_id: int | None
    config_snapshot: dict[str, Any] | None
    started_at: UtcDatetime | None
    ended_at: UtcDatetime | None
    end_reason: str
    #: Ticks stored for the trial, set when it ends (also when interrupted).
    tick_count: int | None = None
    #: Device time gaps or time going backwards in the trial's ticks ({} when none).
    quality_flags: dict[str, Any] | None = None
    #: The hardware profile in effect when the trial started (None: none, or not started).
    hardware_profile_id: int | None = None
    #: The blinding key of the condition ("" before conditions: the controller's name).
    condition: str = ""
    #: population or personal models.
    models: str = "population"
    #: The prior set the condition runs with (None: equal priors).
    prior_set_id: int | None = None
    #: A demonstration block's counts per motion (None for other trials).
    demonstrations: dict[str, Any] | None = None


class LockEventOut(BaseModel):
    """A lock command or mechanism change in a trial."""

    model_config = ConfigDict(from_attributes=True)
    t: float
    side: str
    kind: str
    torque_peak: float | None
