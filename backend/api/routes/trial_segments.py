"""The experimenter's lift segments of a trial: the ground truth of trials whose ticks
carry no simulation labels (hardware). The results use them for the lift tables.

Segments are sample indices from the trial's first tick, as for recordings. They can be
proposed by the same automatic segmentation as recordings, then replaced as a whole list
once the experimenter has checked edges and labels.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Path, Request
from sqlalchemy import delete, select

from backend import audit, tick_queries
from backend.api.deps import CurrentUser, SessionDep
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
from backend.db.evidence import Trial, TrialSegment
from backend.schemas.evidence import SegmentIn, TrialSegmentOut
from controller.segmentation import bridge_gaps, segment_lifts
from controller.tick import MODEL_NAMES

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
def replace_trial_segments(trial_id: TrialId, body: list[SegmentIn], request: Request,
                           user: CurrentUser, db: SessionDep) -> list[TrialSegment]:
    """Replace the trial's segments with this list (the experimenter's checked lifts).
    Each must lie inside the trial's ticks and none may overlap another; an empty list
    removes them all. Nothing changes if any segment is refused."""
    trial = _ran(db, trial_id)
    assert trial.run_id is not None
    n = tick_queries.count(request.app.state.engine, trial.run_id)
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
def auto_segment_trial(trial_id: TrialId, request: Request, user: CurrentUser,
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
    cols = tick_queries.columns(request.app.state.engine, trial.run_id)
    q = np.column_stack([cols["q_left"], cols["q_right"]]).astype(np.float64)
    if q.shape[0] < 100:
        invalid(["trial_id"], f"the trial has {q.shape[0]} ticks: too short to segment")
    try:
        q = bridge_gaps(q)
    except ValueError:
        invalid(["trial_id"], "the trial has no valid hip angles")
    found = segment_lifts(np.arange(q.shape[0], dtype=np.float64) * 0.01, q)
    db.execute(delete(TrialSegment).where(TrialSegment.trial_id == trial.id))
    rows = []
    for seg in found:
        truth = str(cols["truth_activity"][seg.peak])
        rows.append(TrialSegment(trial_id=trial.id, start=seg.start, peak=seg.peak,
                                 end=seg.end, source="auto",
                                 label=truth if truth in MODEL_NAMES else "unlabelled"))
    db.add_all(rows)
    db.flush()
    audit.record(db, user, "segment", "trial", trial.id, {"segments": len(rows)})
    db.commit()
    return rows
