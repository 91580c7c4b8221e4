"""Lift segments, wherever they are marked: in a stopped recording (the demonstrations
the motion models are fitted from) and in a finished trial (the ground truth of a trial
whose ticks carry no simulation labels). Sample indices count from the first tick of
the recording or trial. The queries and writes behind the segment routes; one automatic
proposal for both (`backend.analysis.segmentation`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from typing import Any, TypeVar

import numpy as np
from sqlalchemy import Engine, delete, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.analysis.segmentation import SegmentationError, propose_lifts
from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.evidence_tables import LiftSegment, Recording, Trial, TrialSegment
from backend.db.models import StudySession, User
from backend.schemas.evidence import SegmentIn, SegmentUpdate

Row = TypeVar("Row", Recording, Trial, StudySession, LiftSegment)


def _one(db: Session, kind: type[Row], key: int, entity: str) -> Row:
    row = db.get(kind, key)
    if row is None:
        raise NotFoundError(entity, key)
    return row


# --------------------------------------------------------------------------- recordings


def session_recordings(db: Session, session_id: int) -> list[Recording]:
    """A session's recordings, oldest first."""
    _one(db, StudySession, session_id, "session")
    return list(db.scalars(select(Recording).where(Recording.session_id == session_id)
                           .order_by(Recording.id)))


def recording(db: Session, recording_id: int) -> Recording:
    """One recording; `NotFoundError` if there is none."""
    return _one(db, Recording, recording_id, "recording")


def stopped_recording(db: Session, recording_id: int) -> Recording:
    """A recording whose ticks are stored (stopped, or interrupted when its worker
    stopped: it keeps what it stored); a conflict otherwise."""
    rec = recording(db, recording_id)
    if rec.status not in ("stopped", "interrupted") or rec.run_id is None \
            or rec.first_tick_id is None:
        raise ConflictError("status", f"recording {rec.id} has no stored ticks yet (status "
                            f"{rec.status})")
    return rec


def recording_columns(engine: Engine, rec: Recording) -> dict[str, np.ndarray]:
    """The stored tick columns of a stopped recording."""
    assert rec.run_id is not None
    return tick_queries.columns(engine, rec.run_id, rec.first_tick_id, rec.last_tick_id)


def recording_segments(db: Session, recording_id: int) -> list[LiftSegment]:
    """A recording's lift segments in time order."""
    recording(db, recording_id)
    return list(db.scalars(select(LiftSegment).where(LiftSegment.recording_id == recording_id)
                           .order_by(LiftSegment.start)))


def _proposed(cols: dict[str, np.ndarray], where: str,
              problem: Callable[[SegmentationError], str]) -> list[Any]:
    try:
        return list(propose_lifts(cols))
    except SegmentationError as exc:
        raise InvalidError.at([where], problem(exc)) from exc


def _keep_edited(existing: Sequence[LiftSegment | TrialSegment], replace: bool,
                 problem: str) -> None:
    if any(s.source == "edited" for s in existing) and not replace:
        raise ConflictError("segments", problem)


def auto_segment_recording(db: Session, engine: Engine, user: User, recording_id: int,
                           replace: bool) -> list[LiftSegment]:
    """Find the recording's lifts automatically, in place of its segments; those the
    experimenter edited are kept (a conflict) unless `replace`."""
    rec = stopped_recording(db, recording_id)
    existing = list(db.scalars(select(LiftSegment).where(LiftSegment.recording_id == rec.id)))
    _keep_edited(existing, replace, "some segments were edited by hand; pass replace=true "
                 "to discard them")
    found = _proposed(recording_columns(engine, rec), "recording_id",
                      lambda _e: "the recording is too short or has no valid angles")
    for s in existing:
        db.delete(s)
    out = [LiftSegment(recording_id=rec.id, start=seg.start, peak=seg.peak, end=seg.end,
                       label=seg.label, source="auto") for seg in found]
    db.add_all(out)
    db.flush()
    audit.record(db, user, "segment", "recording", rec.id, {"segments": len(out)})
    db.commit()
    return out


def _check_bounds(rec: Recording, start: int, peak: int, end: int) -> None:
    if not start < peak < end:
        raise InvalidError.at(["body"], "indices must satisfy start < peak < end")
    if rec.first_tick_id is not None and rec.last_tick_id is not None:
        n = rec.last_tick_id - rec.first_tick_id + 1
        if end >= n:
            raise InvalidError.at(["body", "end"], f"end {end} is beyond the recording's "
                                  f"{n} samples")


def add_segment(db: Session, user: User, recording_id: int, body: SegmentIn) -> LiftSegment:
    """A segment added by hand to a stopped recording."""
    rec = stopped_recording(db, recording_id)
    _check_bounds(rec, body.start, body.peak, body.end)
    seg = LiftSegment(recording_id=rec.id, start=body.start, peak=body.peak, end=body.end,
                      label=body.label, source="edited")
    db.add(seg)
    db.flush()
    audit.record(db, user, "create", "segment", seg.id, body.model_dump())
    db.commit()
    return seg


def edit_segment(db: Session, user: User, segment_id: int, body: SegmentUpdate
                 ) -> LiftSegment:
    """An edge dragged or the label changed; the segment becomes the experimenter's."""
    seg = _one(db, LiftSegment, segment_id, "segment")
    rec = recording(db, seg.recording_id)
    changes = body.model_dump(exclude_unset=True, exclude_none=True)
    new = {"start": seg.start, "peak": seg.peak, "end": seg.end, **changes}
    _check_bounds(rec, int(new["start"]), int(new["peak"]), int(new["end"]))
    before = {"start": seg.start, "peak": seg.peak, "end": seg.end, "label": seg.label}
    for k, v in changes.items():
        setattr(seg, k, v)
    seg.source = "edited"
    seg.updated_at = datetime.now(UTC)
    audit.record(db, user, "update", "segment", seg.id, {"before": before, "after": changes})
    db.commit()
    return seg


def delete_segment(db: Session, user: User, segment_id: int) -> None:
    """Remove a recording's segment that is not a lift."""
    seg = _one(db, LiftSegment, segment_id, "segment")
    audit.record(db, user, "delete", "segment", seg.id,
                 {"start": seg.start, "end": seg.end, "label": seg.label})
    db.delete(seg)
    db.commit()


# --------------------------------------------------------------------------- trials


def finished_trial(db: Session, trial_id: int) -> Trial:
    """A trial that ran and ended; a conflict while planned or running."""
    trial = _one(db, Trial, trial_id, "trial")
    if trial.run_id is None or trial.status in ("planned", "running"):
        raise ConflictError("status", f"trial {trial.id} is {trial.status}: segments are "
                            "marked on a finished trial's stored ticks")
    return trial


def _trial_segments(db: Session, trial_id: int) -> list[TrialSegment]:
    return list(db.scalars(select(TrialSegment).where(TrialSegment.trial_id == trial_id)
                           .order_by(TrialSegment.start)))


def trial_segments(db: Session, trial_id: int) -> list[TrialSegment]:
    """The trial's lift segments in time order."""
    _one(db, Trial, trial_id, "trial")
    return _trial_segments(db, trial_id)


def _store_trial_segments(db: Session, user: User, trial: Trial, rows: list[TrialSegment],
                          action: str) -> list[TrialSegment]:
    db.execute(delete(TrialSegment).where(TrialSegment.trial_id == trial.id))
    db.add_all(rows)
    db.flush()
    audit.record(db, user, action, "trial", trial.id, {"segments": len(rows)})
    db.commit()
    return rows


def replace_trial_segments(db: Session, engine: Engine, user: User, trial_id: int,
                           body: Sequence[SegmentIn]) -> list[TrialSegment]:
    """The trial's segments replaced by the experimenter's list: each inside the trial's
    ticks, none overlapping another (every problem named at once; nothing changes)."""
    trial = finished_trial(db, trial_id)
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
        raise InvalidError(problems)
    now = datetime.now(UTC)
    rows = [TrialSegment(trial_id=trial.id, start=s.start, peak=s.peak, end=s.end,
                         label=s.label, source="edited", updated_at=now) for _, s in ordered]
    return _store_trial_segments(db, user, trial, rows, "segments")


def auto_segment_trial(db: Session, engine: Engine, user: User, trial_id: int,
                       replace: bool) -> list[TrialSegment]:
    """Propose the trial's lifts with the recordings' segmentation; the experimenter's
    segments are kept (a conflict) unless `replace`."""
    trial = finished_trial(db, trial_id)
    assert trial.run_id is not None
    _keep_edited(_trial_segments(db, trial.id), replace, "the experimenter set this trial's "
                 "segments; pass replace=true to discard them")
    found = _proposed(tick_queries.columns(engine, trial.run_id), "trial_id",
                      lambda e: f"the trial has {e.samples} ticks: too short to segment"
                      if e.reason == "too_short" else "the trial has no valid hip angles")
    rows = [TrialSegment(trial_id=trial.id, start=seg.start, peak=seg.peak, end=seg.end,
                         source="auto", label=seg.label) for seg in found]
    return _store_trial_segments(db, user, trial, rows, "segment")
