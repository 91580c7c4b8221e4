"""Long use and a wearer's progress: starting the controller in a long-use session, and
the per-wearer learning curves (`backend.analysis.wearer_progress`)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.schemas.fields import MAX_ID, MIN_TIMED_S, UtcDatetime

#: The task of a long-use trial: the wearer works, no task of a trial plan. Results
#: leave these trials out of the study's tables (they are no plan's condition).
LONG_USE_TASK = "long_use"

MetricName = Literal["lifts_per_hour", "recognition_rate", "lock_rate", "time_to_lock_s",
                     "fp_per_hour_walking", "fp_per_hour_stairs"]


class LongUseStartIn(BaseModel):
    """Run a controller for the wearer's work in a long-use session."""

    model_config = ConfigDict(extra="forbid")

    controller: str = Field(min_length=1, max_length=32, description=(
        "a controller of the trial plans (umc, eumc, pec); never a baseline or `none`"))
    model_set_id: int | None = Field(default=None, ge=1, le=MAX_ID, description=(
        "a ready model set of the study (needed by controllers with motion models)"))
    utility_set_id: int | None = Field(default=None, ge=1, le=MAX_ID, description=(
        "a ready utility set at the session's precompression (same controllers)"))
    rate_hz: float | None = Field(default=None, gt=0.0, le=100.0,
                                  description="the controller's rate; the paper's if unset")
    duration_s: float | None = Field(default=None, ge=MIN_TIMED_S, le=24 * 3600.0, description=(
        "end the controller after this much device time; unset: until stopped"))


class ProgressPoint(BaseModel):
    """One session's value of a metric with its 95 % interval (null: no value)."""

    session: int = Field(description="the session's number among the wearer's long-use "
                         "sessions (1 = first)")
    value: float | None
    low: float | None
    high: float | None
    n: float | None = Field(description="what the value rests on: lifts for rates and "
                            "times, hours for per-hour metrics")


class ProgressTrend(BaseModel):
    """Least-squares slope per session and its 95 % interval (null below 3 sessions)."""

    n: int
    slope: float | None
    intercept: float | None
    low: float | None
    high: float | None


class ProgressCurve(BaseModel):
    """A metric over the wearer's sessions and its trend."""

    metric: MetricName
    points: list[ProgressPoint]
    trend: ProgressTrend


class ProgressSession(BaseModel):
    """What one long-use session of the wearer gave."""

    number: int
    session_id: int
    started_at: UtcDatetime
    controllers: list[str]
    trial_ids: list[int]
    truth: list[str] = Field(description="where each trial's lifts and gait came from: "
                             "simulation, segments (with markers for gait), none")
    hours: float
    lifts: int
    confirmed_lifts: int
    unconfirmed_lifts: int
    incomplete_lifts: int
    recognised: int | None
    correct_locks: int
    walking_hours: float
    walking_fp: int
    stairs_hours: float
    stairs_fp: int


class WearerProgressOut(BaseModel):
    """A wearer's long use over sessions: per-session counts and the learning curves."""

    participant_id: int
    participant: str
    controller: str | None = Field(description="the controller the sessions were "
                                   "limited to (null: every controller)")
    sessions: list[ProgressSession]
    curves: list[ProgressCurve]
    skipped: list[dict[str, str | int]]
    notes: list[str]
    long_use_controllers: list[str] = Field(description="the controllers a long-use "
                                            "session may run")
