"""The virtual cohorts' request and answer: what to simulate, and the cohort's record
with its analysis once it is ready."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from backend.schemas.fields import UtcDatetime

#: A console cohort runs on the server's job thread: bounded so one request cannot hold
#: it for long (1,000 participants take a few minutes; the CLI has no such limit).
MAX_API_PARTICIPANTS = 1000

def _cohort_controllers() -> tuple[str, ...]:
    """`controller.evaluation.cohort.cohort_controllers`, imported on first use: the
    cohort engine brings the simulator (SciPy, compiled kernels), which every server start
    would otherwise import with this schema."""
    from controller.evaluation.cohort import cohort_controllers

    return cohort_controllers()


class CohortIn(BaseModel):
    """What to simulate."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(default="", max_length=200)
    participants: int = Field(default=100, ge=2, le=MAX_API_PARTICIPANTS)
    seed: int = Field(default=1, ge=0, le=99_999)
    # Bounded by the validator: each registered plan controller at most once.
    controllers: list[str] = Field(default_factory=lambda: list(_cohort_controllers()),
                                   min_length=1)
    rate_hz: float | None = Field(default=None, ge=1.0, le=100.0, description=(
        "every controller at this rate; null: the paper's rates"))

    @field_validator("controllers")
    @classmethod
    def _known(cls, v: list[str]) -> list[str]:
        known = _cohort_controllers()
        unknown = [c for c in v if c not in known]
        if unknown:
            raise ValueError(f"unknown controller(s) {unknown}; choose from "
                             f"{', '.join(known)}")
        if len(set(v)) != len(v):
            raise ValueError("each controller once")
        return v


class CohortOut(BaseModel):
    """A cohort's record; `result` (the cohort.json document) once it is ready."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    config: dict[str, Any]
    status: str
    error: str
    wall_s: float | None
    created_at: UtcDatetime
    finished_at: UtcDatetime | None
    job_id: int | None = None
    #: The job's progress, 0..1 (also at `GET /api/jobs/{job_id}`).
    progress: float | None = None
    result: dict[str, Any] | None = None
