"""A session's maximum-voluntary-contraction steps: planned per muscle and side with
repetitions, timed in the console by `mvc_start` and `mvc_stop` markers, and turned into
windows of a recording for MVC normalisation (`controller.emg.normalisation`).

Each marker's note says `<muscle> <side> rep <k>`, so the MVC windows can be read back
from the markers alone (an XDF or BIDS consumer sees the same markers); the step keeps
the marker ids of each repetition.
"""

from __future__ import annotations

import threading
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db import audit
from backend.db.emg import EmgRecording, MvcStep
from backend.db.lab import Marker
from backend.db.models import User
from backend.db.sessions import session_row
from backend.emg.recordings import session_montage
from backend.schemas.emg import MvcPlanIn

MVC_START = "mvc_start"
MVC_STOP = "mvc_stop"


class MvcConflictError(ValueError):
    """The step is not in a state where this makes sense."""


class MvcPlanError(ValueError):
    """A planned step the montage cannot record, or a step planned twice; `index` is the
    step's position in the plan."""

    def __init__(self, index: int, problem: str) -> None:
        super().__init__(problem)
        self.index = index


#: Serialises each start/stop's read-check-write: the lab (markers, LSL outlets) lives in
#: this one process, so two concurrent starts cannot both see the step idle.
_EVENT_LOCK = threading.Lock()


def check_plan(body: MvcPlanIn, channels: list[dict[str, Any]]) -> None:
    """Every step's muscle and side(s) in the montage, and no muscle/side planned twice
    ("both" overlaps "left" and "right")."""
    have = {(str(c.get("muscle")), str(c.get("side"))) for c in channels}
    seen: dict[tuple[str, str], int] = {}
    for i, s in enumerate(body.steps):
        sides = ("left", "right") if s.side == "both" else (s.side,)
        missing = [side for side in sides if (s.muscle, side) not in have]
        if missing:
            raise MvcPlanError(i, f"step {i + 1}: {s.muscle} {'/'.join(missing)} is not in "
                               "the study's EMG montage; plan only recorded muscles")
        for side in sides:
            if (s.muscle, side) in seen:
                raise MvcPlanError(i, f"step {i + 1}: {s.muscle} {side} is already planned "
                                   f"in step {seen[(s.muscle, side)] + 1}; plan each "
                                   "muscle and side once (use repetitions)")
            seen[(s.muscle, side)] = i


def steps(db: Session, session_id: int) -> list[MvcStep]:
    """The session's steps in order."""
    return list(db.scalars(select(MvcStep).where(MvcStep.session_id == session_id)
                           .order_by(MvcStep.planned_order, MvcStep.id)))


def plan(db: Session, session_id: int, body: MvcPlanIn) -> list[MvcStep]:
    """Replace the session's steps (none may have run); the caller commits."""
    old = steps(db, session_id)
    if any(s.repetitions_done for s in old):
        raise MvcConflictError("a repetition of this session's MVC steps has run; its "
                               "markers are data, so the plan is kept")
    for s in old:
        db.delete(s)
    rows = [MvcStep(session_id=session_id, planned_order=i, muscle=s.muscle, side=s.side,
                    repetitions=s.repetitions, contraction_s=s.contraction_s,
                    rest_s=s.rest_s, repetitions_done=[])
            for i, s in enumerate(body.steps)]
    db.add_all(rows)
    db.flush()
    return rows


def replan(db: Session, user: User, session_id: int, body: MvcPlanIn) -> list[MvcStep]:
    """Check the plan against the study's montage (`NoMontageError` without one), replace
    the session's steps and write the plan into the audit trail; commits."""
    check_plan(body, session_montage(db, session_id).channels)
    rows = plan(db, session_id, body)
    audit.record(db, user, "plan", "mvc_steps", session_id,
                 {"steps": [s.model_dump() for s in body.steps]})
    db.commit()
    return rows


def step_of(db: Session, session_id: int, step_id: int) -> MvcStep:
    """One MVC step of the session; `NotFoundError` otherwise."""
    return session_row(db, MvcStep, session_id, step_id, "MVC step")


def event(db: Session, lab: Any, step: MvcStep, what: str, user_id: int | None) -> MvcStep:
    """Start or stop the next repetition with a console marker (committed); atomic:
    of concurrent starts (or stops) one wins, the others get `MvcConflictError`."""
    with _EVENT_LOCK:
        db.refresh(step)  # the state as the previous winner committed it
        return _event(db, lab, step, what, user_id)


def _event(db: Session, lab: Any, step: MvcStep, what: str, user_id: int | None) -> MvcStep:
    done = [dict(r) for r in step.repetitions_done]
    running = done[-1] if done and done[-1].get("stop_marker_id") is None else None
    if what == "start":
        if running is not None:
            raise MvcConflictError(f"repetition {running['rep']} is running; stop it first")
        if len(done) >= step.repetitions:
            raise MvcConflictError(f"all {step.repetitions} repetitions of this step are done")
        rep = len(done) + 1
        marker = lab.console_marker(db, step.session_id, MVC_START,
                                    f"{step.muscle} {step.side} rep {rep}", user_id)
        done.append({"rep": rep, "start_marker_id": marker.id, "stop_marker_id": None})
    else:
        if running is None:
            raise MvcConflictError("no repetition is running; start one first")
        marker = lab.console_marker(db, step.session_id, MVC_STOP,
                                    f"{step.muscle} {step.side} rep {running['rep']}",
                                    user_id)
        running["stop_marker_id"] = marker.id
    step.repetitions_done = done
    db.commit()
    db.refresh(step)
    return step


def windows(db: Session, recording: EmgRecording
            ) -> dict[tuple[str, str], list[tuple[float, float]]]:
    """Per (muscle, side): the MVC repetitions as (start, stop) on the recording's own
    clock (file timestamps), from the session's start/stop markers."""
    out: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for step in steps(db, recording.session_id):
        sides = ("left", "right") if step.side == "both" else (step.side,)
        for rep in step.repetitions_done:
            a = db.get(Marker, rep.get("start_marker_id") or -1)
            b = db.get(Marker, rep.get("stop_marker_id") or -1)
            if a is None or b is None or a.lsl_time is None or b.lsl_time is None:
                continue
            span = (a.lsl_time - recording.time_offset_s, b.lsl_time - recording.time_offset_s)
            for side in sides:
                out.setdefault((step.muscle, side), []).append(span)
    return out
