"""The answer of `GET /api/studies/{id}/muscle-results`: a study's muscle activity from
its stored EMG.

The shape is the one `backend.emg.muscle_results.MuscleResults.document` builds (the
results page reads it); these models name every key, so the OpenAPI schema describes it
and a key that goes missing fails the request in the tests, not in the browser. Numbers
that could not be computed (one participant, a flat channel) are null, never NaN.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class _Closed(BaseModel):
    """Every key named: an unexpected key is an error, not silently dropped."""

    model_config = ConfigDict(extra="forbid")


class MuscleMethodOut(_Closed):
    """Everything a reader needs to reproduce the numbers."""

    processing: dict[str, Any] = Field(description="the study's saved EMG processing chain")
    mains_hz: int
    normalisation: str | None = Field(description="mvc, task_peak, task_mean or none")
    normalisation_reference: str
    pad_s: float = Field(description="seconds read either side so the filters settle")
    cycle_points: int = Field(description="points of the normalised lift cycle")
    phases: dict[str, str] = Field(description="how each half of a lift is cut")
    participant_value: str
    interval: str
    reduction: str
    repeated_measures: str
    lift_times: str


class MuscleReferenceOut(_Closed):
    """What one session's envelopes are divided by."""

    method: str = Field(description="mvc, task_peak, task_mean or none (volts)")
    unit: str
    values: list[float | None] = Field(description="per channel, in `channels` order")
    flags: list[str]
    exceeds_mvc: dict[str, float] = Field(
        description="channels whose task activity exceeds the MVC, with the ratio")


class MuscleTrialOut(_Closed):
    """One trial's EMG: its lifts counted, the recordings used and their flags."""

    trial_id: int
    participant: str = Field(description="the participant's pseudonymous code")
    condition: str = Field(description="the controller or baseline the trial ran")
    task: str
    lift_source: str = Field(description="where the lifts came from (truth, segments, "
                             "markers)")
    recordings: list[int]
    lifts: int = Field(description="lifts measured")
    lifts_without_emg: int = Field(description="lifts no recording covers (flag no_emg)")
    flags: list[str]
    channel_flags: dict[str, list[str]]
    note: str


class MuscleSummaryRow(_Closed):
    """One group, metric, condition and channel: the mean over participants."""

    group: str = Field(description="all lifts, or one lift kind")
    metric: str = Field(description="peak, mean or iemg")
    condition: str
    channel: str
    n: int = Field(description="participants")
    mean: float | None
    ci_low: float | None
    ci_high: float | None
    unit: str


class MuscleReductionRow(_Closed):
    """A condition against a baseline on one channel (positive: less activity)."""

    group: str
    metric: str
    channel: str
    condition: str
    baseline: str
    n: int = Field(description="participants with both conditions")
    mean_pct: float | None = Field(description="mean per-participant reduction, %")
    ci_low: float | None
    ci_high: float | None
    p_value: float | None
    p_holm: float | None = Field(description="Holm-corrected over the family")
    test: str


class MuscleReductionGap(_Closed):
    """A baseline x group x metric family without reductions, and why (a baseline trial
    holding only some lift kinds has no baseline data for the other kinds)."""

    baseline: str
    group: str
    metric: str
    gap: str = Field(description="why no reduction is given")


class MuscleRepeatedRow(_Closed):
    """Across all conditions on one channel."""

    group: str
    metric: str
    channel: str
    conditions: list[str]
    n: int
    test: str
    statistic: float | None
    df: int
    p_value: float | None


class MuscleResultsOut(_Closed):
    """A study's muscle activity: per trial, the aggregates and the method."""

    study_id: int
    method: MuscleMethodOut
    channels: list[str] = Field(description="`{muscle}_{side}`, in the montage's order")
    conditions: list[str] = Field(description="conditions with data, in display order")
    baselines: list[str] = Field(description="the baseline conditions with data")
    references: dict[str, MuscleReferenceOut] = Field(description="by session id")
    trials: list[MuscleTrialOut]
    summary: list[MuscleSummaryRow]
    reductions: list[MuscleReductionRow]
    reduction_gaps: list[MuscleReductionGap] = Field(
        description="families without reductions, with the reason")
    repeated_measures: list[MuscleRepeatedRow]
    notes: list[str]
