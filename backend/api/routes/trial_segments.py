"""The experimenter's lift segments of a trial: the ground truth of trials whose ticks
carry no simulation labels (hardware). The results use them for the lift tables.

Segments are sample indices from the trial's first tick, as for recordings. They can be
proposed by the same automatic segmentation as recordings, then replaced as a whole list
once the experimenter has checked edges and labels.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Path
from sqlalchemy import delete, select

from backend.analysis import tick_queries
from backend.analysis.segmentation import SegmentationError, propose_lifts
from backend.api.deps import CurrentUser, EngineDep, SessionDep
from backend.api.errors import (
    AUTH_RESPONSES,
    CONFLICT,
    NOT_FOUND,
    conflict,
    invalid,
    invalid_many,
    one_or_404,
)
from backend.api.params import MAX_ID
from backend.db import audit
from backend.db.evidence_tables import Trial, TrialSegment
from backend.schemas.evidence import SegmentIn, TrialSegmentOut

router = APIRouter(tags=["trials"], responses={**AUTH_RESPONSES, **NOT_FOUND})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


def _ran(db: SessionDep, trial_id: int) -> Trial:
    trial = one_or_404(db, Trial, trial_id, "trial")
    if trial.run_id is None or trial.status in ("planned", "running"):
        conflict("status", f"trial {trial.id} is {trial.status}: segments are marked on a "
                 "finished trial's stored ticks")
    return trial


def _segments(db: SessionDep, trial_id: int) -> list[TrialSegment]:
    return list(db.scalars(select(TrialSegment).where(TrialSegment.trial_id == trial_id)
                           .order_by(TrialSegment.start)))


@router.get("/api/trials/{trial_id}/segments", response_model=list[TrialSegmentOut])
def list_trial_segments(trial_id: TrialId, user: CurrentUser, db: SessionDep
                        ) -> list[TrialSegment]:
    """The trial's lift segments in time order."""
    one_or_404(db, Trial, trial_id, "trial")
    return _segments(db, trial_id)


@router.put("/api/trials/{trial_id}/segments", response_model=list[TrialSegmentOut],
            responses=CONFLICT)
def replace_trial_segments(trial_id: TrialId, body: list[SegmentIn], engine: EngineDep,
                           user: CurrentUser, db: SessionDep) -> list[TrialSegment]:
    """Replace the trial's segments with this list (the experimenter's checked lifts).
    Each must lie inside the trial's ticks and none may overlap another; an empty list
    removes them all. Nothing changes if any segment is refused."""
    trial = _ran(db, trial_id)
    assert trial.run_id is not None
    n = tick_queries.count(engine, trial.run_id)
    problems: list[tuple[list[str | int], str]] = []
    ordered = sorted(enumerate(body), key=lambda x: x[1].start)
    for i, seg in enumerate(body):
        if seg.end >= n:
            problems.append((["body", i, "end"], f"{seg.end} is beyond the trial's {n} ticks"))
    # In start order, any overlap shows between neighbours.
    for (i, a), (j, b) in zip(ordered, ordered[1:], strict=False):
        if b.start <= a.end:
            problems.append((["body", j, "start"], f"segment {j} overlaps segment {i} "
                             f"({a.start}..{a.end})"))
    if problems:
        invalid_many(problems)
    db.execute(delete(TrialSegment).where(TrialSegment.trial_id == trial.id))
    now = datetime.now(UTC)
    rows = [TrialSegment(trial_id=trial.id, start=s.start, peak=s.peak, end=s.end,
                         label=s.label, source="edited", updated_at=now) for _, s in ordered]
    db.add_all(rows)
    db.flush()
    audit.record(db, user, "segments", "trial", trial.id, {"segments": len(rows)})
    db.commit()
    return rows


@router.post("/api/trials/{trial_id}/segment", response_model=list[TrialSegmentOut],
             responses=CONFLICT)
def auto_segment_trial(trial_id: TrialId, engine: EngineDep, user: CurrentUser,
                       db: SessionDep, replace: bool = False) -> list[TrialSegment]:
    """Propose the trial's lifts with the automatic segmentation used for recordings.
    Segments the experimenter set are kept unless `replace=true`. Where the ticks carry
    simulation labels they suggest each label; otherwise segments are "unlabelled" and
    the results ignore the trial until they are labelled."""
    trial = _ran(db, trial_id)
    assert trial.run_id is not None
    existing = _segments(db, trial.id)
    if any(s.source == "edited" for s in existing) and not replace:
        conflict("segments", "the experimenter set this trial's segments; pass replace=true "
                 "to discard them")
    try:
        found = propose_lifts(tick_queries.columns(engine, trial.run_id))
    except SegmentationError as exc:
        invalid(["trial_id"], f"the trial has {exc.samples} ticks: too short to segment"
                if exc.reason == "too_short" else "the trial has no valid hip angles")
    db.execute(delete(TrialSegment).where(TrialSegment.trial_id == trial.id))
    rows = [TrialSegment(trial_id=trial.id, start=seg.start, peak=seg.peak, end=seg.end,
                         source="auto", label=seg.label) for seg in found]
    db.add_all(rows)
    db.flush()
    audit.record(db, user, "segment", "trial", trial.id, {"segments": len(rows)})
    db.commit()
    return rows
