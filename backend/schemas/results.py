"""The answers of the results routes: a study's tables, a trial's what-if replay and the
leave-one-participant-out evaluation of motion models.

The shapes are those `backend.analysis.results` builds (the console reads them); these
models name every key, so the OpenAPI schema describes them and a key that goes missing
fails the request in the tests instead of in the browser.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from backend.schemas.fields import MAX_ID

#: A table cell: a count, a rate, a label, or null where nothing was measured.
Cell = float | int | str | bool | None


class _Closed(BaseModel):
    """Every key named: an unexpected key is an error, not silently dropped."""

    model_config = ConfigDict(extra="forbid")


class TableOut(_Closed):
    """One of the paper's tables."""

    title: str
    header: list[str]
    rows: list[list[Cell]]
    notes: list[str]


class TrialResultOut(_Closed):
    """A completed trial and the ground truth it was scored against."""

    trial_id: int
    participant: str = Field(description="the participant's pseudonymous code")
    controller: str
    condition: str = Field(description="the condition's key the tables use: the "
                           "controller's name, or e.g. umc+personal for its personal "
                           "models")
    task: str
    truth: str = Field(description="where the lifts came from: simulation, segments, "
                       "task or none")
    truth_note: str
    lifts: int
    incomplete_lifts: int
    gait_trials: int
    quality_flags: dict[str, Any] = Field(description="device time gaps, time going "
                                          "backwards (empty when clean)")


class SkippedTrialOut(_Closed):
    """A trial left out of the tables, and why."""

    trial_id: int
    status: str
    reason: str


class StudyResultsOut(_Closed):
    """`GET /api/studies/{id}/results`: the tables of the study's completed trials."""

    study_id: int
    tables: dict[str, TableOut] = Field(description="by table name")
    trials: list[TrialResultOut]
    skipped: list[SkippedTrialOut]
    notes: list[str]


class RunSummaryOut(_Closed):
    """Headline numbers of one run (the stored trial, or its replay)."""

    controller: str
    lifts: int
    recognised: int | None = Field(description="null where the controller estimates no "
                                   "intent")
    decision_correct: int
    decision_wrong: int
    decision_missed: int
    false_positive_signals: int
    gait_trials: int
    lock_ticks: int
    onset_to_lock_median_s: float | None
    ticks: int


class ReplayConfigOut(_Closed):
    """The configuration the replay ran with."""

    controller: str
    settings: dict[str, Any] = Field(description="ControllerConfig fields")
    model_set_id: int | None
    utility_set_id: int | None


class WhatIfOut(_Closed):
    """`POST /api/trials/{id}/what-if`: the stored run and its replay side by side."""

    trial_id: int
    truth: str
    truth_note: str
    original: RunSummaryOut
    replay: RunSummaryOut
    replay_config: ReplayConfigOut


class FoldScoresOut(_Closed):
    """One held-out participant's segments replayed through models fitted without them."""

    participant: str
    segments: int
    recognised: int
    correct: int


class FoldErrorOut(_Closed):
    """A held-out participant whose fold could not be fitted."""

    participant: str
    error: str


class ModelEvaluationOut(_Closed):
    """`GET /api/studies/{id}/model-evaluation`: leave-one-participant-out."""

    model_set_id: int
    utility_set_id: int | None
    settings: dict[str, Any] = Field(description="ControllerConfig fields")
    participants: list[str]
    folds: list[FoldScoresOut | FoldErrorOut]
    segments: int
    recognition_accuracy: float | None
    decision_accuracy: float | None
    recognition_confusion: dict[str, dict[str, int]] = Field(
        description="true motion -> motion whose posterior first reached 0.5 (or none)")
    decision_confusion: dict[str, dict[str, int]] = Field(
        description="true motion -> first lock decision (or missed)")


class WhatIfIn(BaseModel):
    """Another configuration for a stored trial's angles."""

    controller: str = Field(description="umc, eumc, pec or none")
    model_set_id: int | None = Field(default=None, ge=1, le=MAX_ID,
                                     description="default: the trial's model set")
    utility_set_id: int | None = Field(default=None, ge=1, le=MAX_ID,
                                       description="default: the trial's utility set")
    rate_hz: float | None = Field(default=None, gt=0.0, le=100.0,
                                  description="every controller at this rate")
    settings: dict[str, Any] = Field(default_factory=dict, description=(
        "ControllerConfig fields to override (s_req, t_req, d_max, priors, "
        "velocity_threshold, umc_rate_hz, ...)"))
