"""Recording demonstrations on the live path: the worker in recording mode (controller
`none`, no locks) for as long as the recording runs.

The service behind `backend/api/routes/recordings.py`; refusals are `backend.core.errors`.
"""

from __future__ import annotations

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.evidence_tables import Recording
from backend.db.models import StudySession, User
from backend.live.runtime import Runtime
from backend.schemas.evidence import RecordingIn
from backend.schemas.live import SimulationChoice
from backend.study import activity
from controller.controllers import registry
from controller.device.base import SAMPLE_PERIOD_S


async def start(db: Session, user: User, runtime: Runtime, session_id: int,
                body: RecordingIn) -> Recording:
    """Start a recording in the session, under the runtime's activity lock; a conflict
    while a trial or another recording runs (the database's unique index refuses a
    second running recording in any case)."""
    async with runtime.activity:
        try:
            return await _start(db, user, runtime, session_id, body)
        except IntegrityError as exc:
            db.rollback()
            raise ConflictError("recording", "another recording is running: the database "
                                "refused a second") from exc


async def _start(db: Session, user: User, runtime: Runtime, session_id: int,
                 body: RecordingIn) -> Recording:
    if db.get(StudySession, session_id) is None:
        raise NotFoundError("session", session_id)
    activity.ensure_idle(db)
    verdict = runtime.profile_verdict()
    if verdict:  # its angles would be decoded with another device's encoder layout
        raise ConflictError("device", f"no recording: {verdict}")
    sim = body.simulation
    if sim is not None:
        check_simulation(runtime, sim)
    elif body.duration_s is not None:
        raise InvalidError.at(["body", "duration_s"], "a recording is timed only with "
                              "`simulation`: a live wearer's recording ends when stopped")
    try:
        run_id = await runtime.switch_controller(runtime.controller_spec(registry.idle()))
        if sim is not None:
            # The swap starts a run of the recording controller with the new wearer's
            # first sample: that run is the recording's.
            swapped = await runtime.set_simulation(
                sim.seed, sim.script, sim.speed,
                None if body.duration_s is None else round(body.duration_s / SAMPLE_PERIOD_S))
            if swapped is None:
                raise RuntimeError("the worker restarted while the simulation changed")
            run_id = swapped
    except RuntimeError as exc:
        raise ConflictError("worker", str(exc)) from exc
    rec = Recording(session_id=session_id, run_id=run_id, label=body.label, notes=body.notes,
                    status="recording", created_by=user.id)
    db.add(rec)
    db.flush()
    audit.record(db, user, "start", "recording", rec.id, {"run_id": run_id})
    db.commit()
    return rec


def check_simulation(runtime: Runtime, sim: SimulationChoice, what: str = "recording"
                     ) -> None:
    """A 422 naming the field before anything changes: the in-process simulator only,
    and a script it knows (for a recording's or a trial's `simulation`)."""
    if runtime.settings.device_kind != "sim":
        raise InvalidError.at(["body", "simulation"], (
            f"only the in-process simulator (device_kind 'sim') can start a wearer with the "
            f"{what}; this server's device is {runtime.settings.device_kind!r}"))
    # Here, not at the top: the scripts import SciPy's interpolation, a third of a
    # second of the server's start for a request only the simulator's users make.
    from controller.sim.scripts import get_script

    try:
        get_script(sim.script)
    except ValueError as exc:
        raise InvalidError.at(["body", "simulation", "script"], str(exc)) from exc


async def stop(db: Session, user: User, runtime: Runtime, recording_id: int) -> Recording:
    """End the recording: the worker starts a new idle run and the recording's ticks
    are stored and counted."""
    async with runtime.activity:
        rec = db.get(Recording, recording_id)
        if rec is None:
            raise NotFoundError("recording", recording_id)
        if rec.status != "recording":
            raise ConflictError("status", f"recording {rec.id} is already {rec.status}")
        # A worker that died has stored what it recorded and closed the run with it.
        await runtime.idle()
        runtime.recorder.flush()
        if not activity.close_recording(db, runtime.recorder.engine, rec.id, "stopped"):
            db.refresh(rec)  # closed meanwhile: its worker stopped
            raise ConflictError("status", f"recording {rec.id} is already {rec.status}")
        db.refresh(rec)
        audit.record(db, user, "stop", "recording", rec.id,
                     {"first_tick_id": rec.first_tick_id, "last_tick_id": rec.last_tick_id})
        db.commit()
        return rec
