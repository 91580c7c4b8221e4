"""Request and response bodies of the replication API (`backend/api/routes/replication.py`)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field


class ReplicationIn(BaseModel):
    """What to run: seeds (virtual studies) of `participants` each."""

    # DEFAULT_SEEDS of controller.evaluation.paper_claims, not imported: it is slow to
    # load and this module loads with the server.
    seeds: int = Field(20, ge=2, le=20, description="virtual studies (2..20)")
    participants: int = Field(8, ge=2, le=40, description="participants per seed")


class ReplicationStarted(BaseModel):
    """The queued job and the folder its report will be written to."""

    job_id: int
    folder: str


class ReplicationJobOut(BaseModel):
    """The newest replication job."""

    id: int
    status: str
    progress: float
    message: str | None = None


class ClaimIntervalOut(BaseModel):
    """Mean over seeds, its 95 % t interval and the seeds' SD (None where undefined)."""

    n: int
    mean: float | None = None
    low: float | None = None
    high: float | None = None
    sd: float | None = None


class ClaimOut(BaseModel):
    """One claim of the paper with the virtual number and the verdict."""

    key: str
    source: str
    statement: str
    kind: str
    paper: float | None = None
    unit: str = ""
    interval: ClaimIntervalOut
    verdict: str
    reason: str
    #: Table claims: virtual minus paper with both errors (Welch interval, TOST).
    difference: dict[str, float | None] | None = None
    #: The two halves of the seeds gave different verdicts (None: too few seeds).
    unstable: bool | None = None


class ReplicationReportOut(BaseModel):
    """The newest finished report."""

    folder: str
    wall_s: float | None = None
    config: dict[str, Any] = Field(default_factory=dict)
    claims: list[ClaimOut]


class ReplicationStateOut(BaseModel):
    """The newest job and the newest report; either may be absent."""

    job: ReplicationJobOut | None = None
    report: ReplicationReportOut | None = None
