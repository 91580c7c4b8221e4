"""Data collection: record demonstrations, segment them into lifts, edit and label them."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Path
from sqlalchemy import select

from backend.analysis import tick_queries
from backend.analysis.segmentation import SegmentationError, propose_lifts
from backend.api.deps import CurrentUser, EngineDep, RuntimeDep, SessionDep
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, conflict, invalid, one_or_404
from backend.api.params import MAX_ID, SessionId
from backend.db import audit
from backend.db.evidence_tables import LiftSegment, Recording
from backend.db.models import StudySession
from backend.schemas.evidence import (
    RecordingAngles,
    RecordingIn,
    RecordingOut,
    SegmentIn,
    SegmentOut,
    SegmentUpdate,
)
from backend.study import recordings

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
    one_or_404(db, StudySession, session_id, "session")
    return list(db.scalars(select(Recording).where(Recording.session_id == session_id)
                           .order_by(Recording.id)))


@router.get("/api/recordings/{recording_id}", response_model=RecordingOut)
def get_recording(recording_id: RecordingId, user: CurrentUser, db: SessionDep) -> Recording:
    """One recording."""
    return one_or_404(db, Recording, recording_id, "recording")


def _stopped(db: SessionDep, recording_id: int) -> Recording:
    rec = one_or_404(db, Recording, recording_id, "recording")
    # An interrupted recording (its worker stopped) keeps the ticks it stored.
    if rec.status not in ("stopped", "interrupted") or rec.run_id is None \
            or rec.first_tick_id is None:
        conflict("status", f"recording {rec.id} has no stored ticks yet (status {rec.status})")
    return rec


def _angles(engine: EngineDep, rec: Recording) -> dict[str, np.ndarray]:
    assert rec.run_id is not None
    return tick_queries.columns(engine, rec.run_id, rec.first_tick_id, rec.last_tick_id)


@router.get("/api/recordings/{recording_id}/angles", response_model=RecordingAngles,
            responses=CONFLICT)
def recording_angles(recording_id: RecordingId, engine: EngineDep, user: CurrentUser,
                     db: SessionDep) -> RecordingAngles:
    """Hip angles (rad) and device time (s) of a stopped recording."""
    cols = _angles(engine, _stopped(db, recording_id))

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
    rec = _stopped(db, recording_id)
    existing = list(db.scalars(select(LiftSegment).where(LiftSegment.recording_id == rec.id)))
    if any(s.source == "edited" for s in existing) and not replace:
        conflict("segments", "some segments were edited by hand; pass replace=true to "
                 "discard them")
    try:
        found = propose_lifts(_angles(engine, rec))
    except SegmentationError:
        invalid(["recording_id"], "the recording is too short or has no valid angles")
    for s in existing:
        db.delete(s)
    out = []
    for seg in found:
        row = LiftSegment(recording_id=rec.id, start=seg.start, peak=seg.peak, end=seg.end,
                          label=seg.label, source="auto")
        db.add(row)
        out.append(row)
    db.flush()
    audit.record(db, user, "segment", "recording", rec.id, {"segments": len(out)})
    db.commit()
    return out


@router.get("/api/recordings/{recording_id}/segments", response_model=list[SegmentOut])
def list_segments(recording_id: RecordingId, user: CurrentUser, db: SessionDep
                  ) -> list[LiftSegment]:
    """A recording's lift segments in time order."""
    one_or_404(db, Recording, recording_id, "recording")
    return list(db.scalars(select(LiftSegment).where(LiftSegment.recording_id == recording_id)
                           .order_by(LiftSegment.start)))


def _check_bounds(db: SessionDep, rec: Recording, start: int, peak: int, end: int) -> None:
    if not start < peak < end:
        invalid(["body"], "indices must satisfy start < peak < end")
    if rec.first_tick_id is not None and rec.last_tick_id is not None:
        n = rec.last_tick_id - rec.first_tick_id + 1
        if end >= n:
            invalid(["body", "end"], f"end {end} is beyond the recording's {n} samples")


@router.post("/api/recordings/{recording_id}/segments", response_model=SegmentOut,
             status_code=201, responses=CONFLICT)
def add_segment(recording_id: RecordingId, body: SegmentIn, user: CurrentUser,
                db: SessionDep) -> LiftSegment:
    """Add a segment by hand."""
    rec = _stopped(db, recording_id)
    _check_bounds(db, rec, body.start, body.peak, body.end)
    seg = LiftSegment(recording_id=rec.id, start=body.start, peak=body.peak, end=body.end,
                      label=body.label, source="edited")
    db.add(seg)
    db.flush()
    audit.record(db, user, "create", "segment", seg.id, body.model_dump())
    db.commit()
    return seg


@router.patch("/api/segments/{segment_id}", response_model=SegmentOut)
def edit_segment(segment_id: SegmentId, body: SegmentUpdate, user: CurrentUser,
                 db: SessionDep) -> LiftSegment:
    """Drag an edge or change the label."""
    seg = one_or_404(db, LiftSegment, segment_id, "segment")
    rec = one_or_404(db, Recording, seg.recording_id, "recording")
    changes = body.model_dump(exclude_unset=True, exclude_none=True)
    new = {"start": seg.start, "peak": seg.peak, "end": seg.end, **changes}
    _check_bounds(db, rec, int(new["start"]), int(new["peak"]), int(new["end"]))
    before = {"start": seg.start, "peak": seg.peak, "end": seg.end, "label": seg.label}
    for k, v in changes.items():
        setattr(seg, k, v)
    seg.source = "edited"
    seg.updated_at = datetime.now(UTC)
    audit.record(db, user, "update", "segment", seg.id, {"before": before, "after": changes})
    db.commit()
    return seg


@router.delete("/api/segments/{segment_id}", status_code=204)
def delete_segment(segment_id: SegmentId, user: CurrentUser, db: SessionDep) -> None:
    """Remove a segment that is not a lift."""
    seg = one_or_404(db, LiftSegment, segment_id, "segment")
    audit.record(db, user, "delete", "segment", seg.id,
                 {"start": seg.start, "end": seg.end, "label": seg.label})
    db.delete(seg)
    db.commit()
