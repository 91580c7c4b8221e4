"""The experimenter's lift segments of a trial: the ground truth of trials whose ticks
carry no simulation labels (hardware). The results use them for the lift tables.

Segments are sample indices from the trial's first tick, as for recordings. They can be
proposed by the same automatic segmentation as recordings, then replaced as a whole list
once the experimenter has checked edges and labels.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path

from backend.api.deps import CurrentUser, EngineDep, SessionDep
from backend.api.errors import (
    AUTH_RESPONSES,
    CONFLICT,
    NOT_FOUND,
)
from backend.api.params import MAX_ID
from backend.db.evidence_tables import TrialSegment
from backend.schemas.evidence import SegmentIn, TrialSegmentOut
from backend.study import segments

router = APIRouter(tags=["trials"], responses={**AUTH_RESPONSES, **NOT_FOUND})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


@router.get("/api/trials/{trial_id}/segments", response_model=list[TrialSegmentOut])
def list_trial_segments(trial_id: TrialId, user: CurrentUser, db: SessionDep
                        ) -> list[TrialSegment]:
    """The trial's lift segments in time order."""
    return segments.trial_segments(db, trial_id)


@router.put("/api/trials/{trial_id}/segments", response_model=list[TrialSegmentOut],
            responses=CONFLICT)
def replace_trial_segments(trial_id: TrialId, body: list[SegmentIn], engine: EngineDep,
                           user: CurrentUser, db: SessionDep) -> list[TrialSegment]:
    """Replace the trial's segments with this list (the experimenter's checked lifts).
    Each must lie inside the trial's ticks and none may overlap another; an empty list
    removes them all. Nothing changes if any segment is refused."""
    return segments.replace_trial_segments(db, engine, user, trial_id, body)


@router.post("/api/trials/{trial_id}/segment", response_model=list[TrialSegmentOut],
             responses=CONFLICT)
def auto_segment_trial(trial_id: TrialId, engine: EngineDep, user: CurrentUser,
                       db: SessionDep, replace: bool = False) -> list[TrialSegment]:
    """Propose the trial's lifts with the automatic segmentation used for recordings.
    Segments the experimenter set are kept unless `replace=true`. Where the ticks carry
    simulation labels they suggest each label; otherwise segments are "unlabelled" and
    the results ignore the trial until they are labelled."""
    return segments.auto_segment_trial(db, engine, user, trial_id, replace)
