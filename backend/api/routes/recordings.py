"""Data collection: record demonstrations, segment them into lifts, edit and label them."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, Path

from backend.api.deps import CurrentUser, EngineDep, RuntimeDep, SessionDep
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND
from backend.api.params import MAX_ID, SessionId
from backend.db.evidence_tables import LiftSegment, Recording
from backend.schemas.evidence import (
    RecordingAngles,
    RecordingIn,
    RecordingOut,
    SegmentIn,
    SegmentOut,
    SegmentUpdate,
)
from backend.study import recordings, segments

router = APIRouter(tags=["recordings"], responses={**AUTH_RESPONSES, **NOT_FOUND})

RecordingId = Annotated[int, Path(ge=1, le=MAX_ID, description="recording id")]
SegmentId = Annotated[int, Path(ge=1, le=MAX_ID, description="segment id")]


@router.post("/api/sessions/{session_id}/recordings", response_model=RecordingOut,
             status_code=201, responses=CONFLICT)
async def start_recording(session_id: SessionId, body: RecordingIn, user: CurrentUser,
                          db: SessionDep, runtime: RuntimeDep) -> Recording:
    """Put the worker in recording mode (no locks) and start a recording. 409 while a
    trial or another recording runs (under the runtime's activity lock; the database's
    unique index refuses a second running recording in any case)."""
    return await recordings.start(db, user, runtime, session_id, body)


@router.post("/api/recordings/{recording_id}/stop", response_model=RecordingOut,
             responses=CONFLICT)
async def stop_recording(recording_id: RecordingId, user: CurrentUser, db: SessionDep,
                         runtime: RuntimeDep) -> Recording:
    """End the recording: the worker starts a new idle run and the ticks are stored."""
    return await recordings.stop(db, user, runtime, recording_id)


@router.get("/api/sessions/{session_id}/recordings", response_model=list[RecordingOut])
def list_recordings(session_id: SessionId, user: CurrentUser, db: SessionDep
                    ) -> list[Recording]:
    """A session's recordings, oldest first."""
    return segments.session_recordings(db, session_id)


@router.get("/api/recordings/{recording_id}", response_model=RecordingOut)
def get_recording(recording_id: RecordingId, user: CurrentUser, db: SessionDep) -> Recording:
    """One recording."""
    return segments.recording(db, recording_id)


@router.get("/api/recordings/{recording_id}/angles", response_model=RecordingAngles,
            responses=CONFLICT)
def recording_angles(recording_id: RecordingId, engine: EngineDep, user: CurrentUser,
                     db: SessionDep) -> RecordingAngles:
    """Hip angles (rad) and device time (s) of a stopped recording."""
    cols = segments.recording_columns(engine, segments.stopped_recording(db, recording_id))

    def clean(a: np.ndarray) -> list[float | None]:
        return [None if np.isnan(v) else float(v) for v in a]

    return RecordingAngles(t=[float(v) for v in cols["t"]], q_left=clean(cols["q_left"]),
                           q_right=clean(cols["q_right"]),
                           truth_activity=[str(v) for v in cols["truth_activity"]])


@router.post("/api/recordings/{recording_id}/segment", response_model=list[SegmentOut],
             responses=CONFLICT)
def auto_segment(recording_id: RecordingId, engine: EngineDep, user: CurrentUser,
                 db: SessionDep, replace: bool = False) -> list[LiftSegment]:
    """Find the lifts automatically. Segments the experimenter edited are kept unless
    `replace=true`. In simulation the ground truth suggests each segment's label."""
    return segments.auto_segment_recording(db, engine, user, recording_id, replace)


@router.get("/api/recordings/{recording_id}/segments", response_model=list[SegmentOut])
def list_segments(recording_id: RecordingId, user: CurrentUser, db: SessionDep
                  ) -> list[LiftSegment]:
    """A recording's lift segments in time order."""
    return segments.recording_segments(db, recording_id)


@router.post("/api/recordings/{recording_id}/segments", response_model=SegmentOut,
             status_code=201, responses=CONFLICT)
def add_segment(recording_id: RecordingId, body: SegmentIn, user: CurrentUser,
                db: SessionDep) -> LiftSegment:
    """Add a segment by hand."""
    return segments.add_segment(db, user, recording_id, body)


@router.patch("/api/segments/{segment_id}", response_model=SegmentOut)
def edit_segment(segment_id: SegmentId, body: SegmentUpdate, user: CurrentUser,
                 db: SessionDep) -> LiftSegment:
    """Drag an edge or change the label."""
    return segments.edit_segment(db, user, segment_id, body)


@router.delete("/api/segments/{segment_id}", status_code=204)
def delete_segment(segment_id: SegmentId, user: CurrentUser, db: SessionDep) -> None:
    """Remove a segment that is not a lift."""
    segments.delete_segment(db, user, segment_id)
