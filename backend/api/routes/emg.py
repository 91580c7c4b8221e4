"""Muscle activity: a study's montage and EMG analysis settings, a session's EMG from LSL
and from EDF/BDF and XDF files, its recordings, and its MVC steps."""

from __future__ import annotations

import asyncio
import threading
from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, HTTPException, Path, Query, UploadFile
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.api.deps import (
    CurrentUser,
    EmgLabDep,
    EngineDep,
    LabDep,
    SessionDep,
    SettingsDep,
)
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    NOT_FOUND,
    conflict,
    invalid,
    invalid_many,
    not_found,
    one_or_404,
)
from backend.api.params import MAX_ID, SessionId, StudyId
from backend.core.config import Settings
from backend.db import audit
from backend.db.emg import (
    EmgAnalysisSettings,
    EmgMontage,
    EmgRecording,
    EmgStream,
    MvcStep,
)
from backend.db.evidence_tables import Trial
from backend.db.models import Study, StudySession
from backend.emg import edf_import, mvc, recordings
from backend.emg.live import EmgLab
from backend.emg.recordings import ChannelMismatchError, NoMontageError
from backend.lab import xdf_emg
from backend.schemas.emg import (
    EmgRecordingOut,
    EmgSettingsIn,
    EmgSettingsOut,
    EmgStreamIn,
    EmgStreamOut,
    MontageIn,
    MontageOut,
    MvcEventIn,
    MvcPlanIn,
    MvcStepOut,
    TrialEmgOut,
)
from controller.emg.montage import normalise_label
from controller.emg.processing import EmgProcessing, EmgSettingsError

router = APIRouter(tags=["emg"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})
#: Tries of a write that concurrent requests race for before it is a 409.
WRITE_ATTEMPTS = 5

EmgStreamId = Annotated[int, Path(ge=1, le=MAX_ID, description="EMG subscription id")]
EmgRecordingId = Annotated[int, Path(ge=1, le=MAX_ID, description="EMG recording id")]
MvcStepId = Annotated[int, Path(ge=1, le=MAX_ID, description="MVC step id")]
TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


# Montage ------------------------------------------------------------------------------------
def _montage_out(row: EmgMontage) -> MontageOut:
    return MontageOut(id=row.id, study_id=row.study_id, version=row.version,
                      created_at=row.created_at, placement_scheme=row.placement_scheme,
                      channels=row.channels)  # type: ignore[arg-type]


def _check_montage(body: MontageIn) -> None:
    """Repeated labels or (muscle, side): 422 naming each repeated entry's field."""
    problems: list[tuple[list[str | int], str]] = []
    labels: dict[str, int] = {}
    pairs: dict[tuple[str, str], int] = {}
    for i, c in enumerate(body.channels):
        key = normalise_label(c.label)
        if not key:
            problems.append((["body", "channels", i, "label"], "a channel label needs a "
                             "letter or digit"))
        elif key in labels:
            problems.append((["body", "channels", i, "label"],
                             f"duplicate channel: label {c.label!r} is also channel "
                             f"{labels[key]}"))
        else:
            labels[key] = i
        pair = (c.muscle, c.side)
        if pair in pairs:
            problems.append((["body", "channels", i, "muscle"],
                             f"duplicate channel: {c.side} {c.muscle} is also channel "
                             f"{pairs[pair]}"))
        else:
            pairs[pair] = i
    if problems:
        invalid_many(problems)


@router.get("/api/studies/{study_id}/emg-montage", response_model=MontageOut)
def get_montage(study_id: StudyId, user: CurrentUser, db: SessionDep) -> MontageOut:
    """The study's current montage (its newest version); 404 before the first."""
    one_or_404(db, Study, study_id, "study")
    row = recordings.current_montage(db, study_id)
    if row is None:
        not_found("EMG montage of study", study_id)
    return _montage_out(row)


@router.get("/api/studies/{study_id}/emg-montages", response_model=list[MontageOut])
def list_montages(study_id: StudyId, user: CurrentUser, db: SessionDep) -> list[MontageOut]:
    """Every version of the study's montage, oldest first."""
    one_or_404(db, Study, study_id, "study")
    return [_montage_out(r) for r in db.scalars(
        select(EmgMontage).where(EmgMontage.study_id == study_id)
        .order_by(EmgMontage.version))]


@router.put("/api/studies/{study_id}/emg-montage", response_model=MontageOut,
            responses=CONFLICT)
def put_montage(study_id: StudyId, body: MontageIn, user: CurrentUser,
                db: SessionDep) -> MontageOut:
    """A new version of the study's montage (older versions stay: recordings keep the
    version their channels were mapped by). Unknown muscles and repeated channels are
    a 422 naming the field."""
    one_or_404(db, Study, study_id, "study")
    _check_montage(body)
    # Concurrent PUTs race for the next version number (unique per study): the loser
    # takes the one after; 409 only if it keeps losing.
    for _attempt in range(WRITE_ATTEMPTS):
        latest = db.scalar(select(func.max(EmgMontage.version))
                           .where(EmgMontage.study_id == study_id)) or 0
        row = EmgMontage(study_id=study_id, version=latest + 1,
                         placement_scheme=body.placement_scheme,
                         channels=[c.model_dump() for c in body.channels], created_by=user.id)
        db.add(row)
        try:
            db.flush()
            audit.record(db, user, "update", "emg_montage", study_id,
                         {"version": row.version, "channels": len(body.channels)})
            db.commit()
        except IntegrityError:
            db.rollback()
            continue
        return _montage_out(row)
    conflict("montage", "other montage versions were being saved at the same time; "
             "send it again")


@router.delete("/api/studies/{study_id}/emg-montage", response_model=list[MontageOut],
               responses=CONFLICT)
def delete_montage(study_id: StudyId, user: CurrentUser, db: SessionDep) -> list[MontageOut]:
    """Remove the study's montage (every version); 409 once a recording or a
    subscription uses one (a recording's channels must stay mapped)."""
    one_or_404(db, Study, study_id, "study")
    rows = list(db.scalars(select(EmgMontage).where(EmgMontage.study_id == study_id)))
    ids = [r.id for r in rows] or [-1]
    used = db.scalar(select(func.count()).select_from(EmgRecording)
                     .where(EmgRecording.montage_id.in_(ids)))
    subs = db.scalar(select(func.count()).select_from(EmgStream)
                     .where(EmgStream.montage_id.in_(ids)))
    if used or subs:
        conflict("montage", f"{used} recordings and {subs} EMG subscriptions use the "
                 "study's montage; change it with PUT (a new version) instead")
    out = [_montage_out(r) for r in rows]
    for r in rows:
        db.delete(r)
    audit.record(db, user, "delete", "emg_montage", study_id, {"versions": len(rows)})
    db.commit()
    return out


# Analysis settings --------------------------------------------------------------------------
def _settings_out(row: EmgAnalysisSettings | None) -> EmgSettingsOut:
    proc = EmgProcessing.from_dict(row.processing) if row is not None else EmgProcessing()
    return EmgSettingsOut(processing=proc.to_dict(), normalisation=proc.normalisation,
                          mains_hz=row.mains_hz if row is not None else 50)


@router.get("/api/studies/{study_id}/emg-settings", response_model=EmgSettingsOut)
def get_emg_settings(study_id: StudyId, user: CurrentUser, db: SessionDep) -> EmgSettingsOut:
    """The study's EMG processing chain and normalisation (defaults until set)."""
    one_or_404(db, Study, study_id, "study")
    return _settings_out(db.get(EmgAnalysisSettings, study_id))


@router.put("/api/studies/{study_id}/emg-settings", response_model=EmgSettingsOut,
            responses=CONFLICT)
def put_emg_settings(study_id: StudyId, body: EmgSettingsIn, user: CurrentUser,
                     db: SessionDep) -> EmgSettingsOut:
    """Set the study's EMG processing chain and normalisation method; every parameter is
    stored (defaults filled in) and written into results and exports."""
    one_or_404(db, Study, study_id, "study")
    data = dict(body.processing)
    if body.normalisation is not None:
        data["normalisation"] = body.normalisation
    try:
        proc = EmgProcessing.from_dict(data)
    except (EmgSettingsError, TypeError) as exc:
        invalid(["body", "processing"], str(exc))
    # Concurrent first PUTs both insert the study's row: the loser updates the winner's.
    for _attempt in range(WRITE_ATTEMPTS):
        row = db.get(EmgAnalysisSettings, study_id)
        if row is None:
            row = EmgAnalysisSettings(study_id=study_id)
            db.add(row)
        row.processing = proc.to_dict()
        row.mains_hz = body.mains_hz
        row.updated_at = datetime.now(UTC)
        try:
            audit.record(db, user, "update", "emg_settings", study_id, row.processing)
            db.commit()
        except IntegrityError:
            db.rollback()
            continue
        return _settings_out(row)
    conflict("emg_settings", "the settings were being saved by another request at the "
             "same time; send them again")


# Live EMG from LSL --------------------------------------------------------------------------
def _stream_out(emg: EmgLab, sub: EmgStream) -> EmgStreamOut:
    out = EmgStreamOut.model_validate(sub)
    inlet = emg.inlets.get(sub.id)
    out.connected = bool(inlet is not None and inlet.connected)
    out.last_time = inlet.last_time if inlet is not None else None
    return out


def _mismatch(loc: list[str | int], exc: ChannelMismatchError) -> None:
    raise HTTPException(422, [{"loc": loc, "msg": str(exc), "type": "value_error",
                               "unmatched_labels": exc.unmatched,
                               "missing_labels": exc.missing,
                               "expected_labels": exc.expected}])


#: Serialises the duplicate check and the insert of a subscription (a request handler's
#: synchronous section; held for one query and one commit).
_SUBSCRIBE_LOCK = threading.Lock()


def _same_stream(other: EmgStream, name: str, source_id: str) -> bool:
    """Whether an existing subscription records the stream resolved as name/source id."""
    if source_id and other.source_id:
        return other.source_id == source_id
    return other.name == name


def _already_recorded(db: Session, other: EmgStream, session_id: int, key: str) -> None:
    """409 for a stream already recorded; another study's session stays unnamed."""
    from backend.db.sessions import study_of_session

    if study_of_session(db, other.session_id) == study_of_session(db, session_id):
        where = f"session {other.session_id} of this study"
    else:
        where = "a session of another study"
    conflict("source_id", f"{where} already records the LSL stream {key!r}; one recording "
             "per stream: unsubscribe it there first")


@router.get("/api/sessions/{session_id}/emg-streams", response_model=list[EmgStreamOut])
def list_emg_streams(session_id: SessionId, user: CurrentUser, db: SessionDep,
                     emg: EmgLabDep) -> list[EmgStreamOut]:
    """The session's EMG stream subscriptions."""
    one_or_404(db, StudySession, session_id, "session")
    return [_stream_out(emg, s) for s in db.scalars(
        select(EmgStream).where(EmgStream.session_id == session_id).order_by(EmgStream.id))]


@router.post("/api/sessions/{session_id}/emg-streams", response_model=EmgStreamOut,
             status_code=201, responses=CONFLICT)
async def subscribe_emg(session_id: SessionId, body: EmgStreamIn, user: CurrentUser,
                        db: SessionDep, emg: EmgLabDep) -> EmgStreamOut:
    """Record this LSL EMG stream with the session from now on, in chunks to the EMG
    folder, on this server's LSL clock (clock correction). The stream must be visible
    (409 otherwise), of type EMG, in volts (V, mV, uV), and its channel labels must match
    the study's montage (422 listing unmatched and expected labels); nothing is stored
    otherwise."""
    from backend.emg import live

    one_or_404(db, StudySession, session_id, "session")
    if not emg.enabled:
        conflict("lsl", "the Lab Streaming Layer is switched off (EXOSTUDY_LSL_ENABLED)")
    try:
        montage = recordings.session_montage(db, session_id)
    except NoMontageError as exc:
        conflict("montage", str(exc))
    key = body.source_id or body.name
    info = await asyncio.to_thread(live.resolve_described, body.name, body.source_id)
    if info is None:
        conflict("name", f"no LSL stream {key!r} is visible now")
    try:
        live.layout_of(info, montage, body.ignore_labels)
    except ChannelMismatchError as exc:
        _mismatch(["body", "name"], exc)
    except ValueError as exc:
        invalid(["body", "name"], f"stream {key!r}: {exc}")
    # The stream's identity is what it resolved to (its source id, else its name), so a
    # subscription by name and one by name + source id are the same stream. Check and
    # insert with no await between them and under a lock, so concurrent requests cannot
    # both pass the check.
    resolved_sid, resolved_name = str(info.source_id()), str(info.name())
    with _SUBSCRIBE_LOCK:
        for other in db.scalars(select(EmgStream).where(EmgStream.active)):
            if _same_stream(other, resolved_name, resolved_sid):
                _already_recorded(db, other, session_id, key)
        sub = EmgStream(session_id=session_id, name=body.name,
                        source_id=body.source_id or resolved_sid, montage_id=montage.id,
                        ignored_labels=body.ignore_labels, active=True, error="")
        db.add(sub)
        db.flush()
        audit.record(db, user, "create", "emg_stream", sub.id, body.model_dump())
        db.commit()
    emg.subscribe(sub.id)
    return _stream_out(emg, sub)


@router.delete("/api/sessions/{session_id}/emg-streams/{emg_stream_id}",
               response_model=EmgStreamOut)
async def unsubscribe_emg(session_id: SessionId, emg_stream_id: EmgStreamId,
                          user: CurrentUser, db: SessionDep, emg: EmgLabDep
                          ) -> EmgStreamOut:
    """Stop recording the stream; the recording so far is finished and kept."""
    sub = db.get(EmgStream, emg_stream_id)
    if sub is None or sub.session_id != session_id:
        not_found("EMG subscription", emg_stream_id)
    await asyncio.to_thread(emg.unsubscribe, sub.id)
    db.refresh(sub)
    sub.active = False
    audit.record(db, user, "delete", "emg_stream", sub.id, {})
    db.commit()
    return _stream_out(emg, sub)


# Files -------------------------------------------------------------------------------------
def _mains(db: Session, session_id: int) -> int:
    from backend.db.sessions import study_of_session

    sid = study_of_session(db, session_id)
    row = db.get(EmgAnalysisSettings, sid) if sid is not None else None
    return row.mains_hz if row is not None else 50


def _labels(text: str) -> list[str]:
    return [s.strip() for s in text.split(",") if s.strip()]


@router.post("/api/sessions/{session_id}/emg/edf", response_model=EmgRecordingOut,
             status_code=201, responses={413: {"description": "the file is too large"},
                                         **CONFLICT})
async def import_edf(
    session_id: SessionId, user: CurrentUser, db: SessionDep, settings: SettingsDep,
    file: Annotated[UploadFile, File(description="an EDF, EDF+, BDF or BDF+ file")],
    marker: Annotated[str | None, Form(max_length=100, description=(
        "align by this annotation text, also the label of a session marker"))] = None,
    trial: Annotated[int | None, Form(ge=1, le=MAX_ID, description=(
        "align: the file starts offset_s after this trial's start"))] = None,
    offset_s: Annotated[float, Form(ge=-86400, le=86400)] = 0.0,
    ignore_labels: Annotated[str, Form(max_length=4000, description=(
        "comma-separated channel labels to leave out (spare inputs)"))] = "",
) -> EmgRecording:
    """Import an EDF/BDF file's EMG as a recording of the session: channels mapped by
    the study's montage (422 listing unmatched and expected labels), units converted to
    volts (422 if not a voltage), placed on the session clock by `marker` or by `trial`
    and `offset_s` (422 if neither or it cannot be found). Nothing is stored on error."""
    one_or_404(db, StudySession, session_id, "session")
    limit = settings.max_upload_bytes
    data = await file.read(limit + 1)
    if len(data) > limit:
        raise HTTPException(413, f"file: larger than {limit} bytes")
    how = edf_import.Alignment(marker=marker or None, trial=trial, offset_s=offset_s)
    return await _import(db, settings, session_id, lambda: edf_import.import_file(
        db, settings, session_id, data, file.filename or "recording.edf", how,
        _labels(ignore_labels), user.id, _mains(db, session_id)), user)


@router.post("/api/sessions/{session_id}/emg/xdf", response_model=EmgRecordingOut,
             status_code=201, responses={413: {"description": "the file is too large"},
                                         **CONFLICT})
async def import_xdf(
    session_id: SessionId, user: CurrentUser, db: SessionDep, settings: SettingsDep,
    engine: EngineDep,
    file: Annotated[UploadFile, File(description="a LabRecorder .xdf file")],
    stream: Annotated[str | None, Form(max_length=200, description=(
        "the EMG stream's name or stream id (needed only when the file has several)"))
    ] = None,
    ignore_labels: Annotated[str, Form(max_length=4000, description=(
        "comma-separated channel labels to leave out (spare inputs)"))] = "",
) -> EmgRecording:
    """Import the EMG stream of a LabRecorder XDF file as a recording of the session:
    read by the bounded XDF reader (its `xdf_max_*` limits), put on the session clock
    through the file's clock offsets and ExoStudy's tick stream in the same file, the
    channels mapped by the study's montage (422 listing unmatched and expected labels),
    units converted to volts (422 if not a voltage). NaN samples, a rate that disagrees
    with the time stamps and gaps are stored and flagged. Nothing is stored on error."""
    one_or_404(db, StudySession, session_id, "session")
    limit = settings.max_upload_bytes
    data = await file.read(limit + 1)
    if len(data) > limit:
        raise HTTPException(413, f"file: larger than {limit} bytes")
    return await _import(db, settings, session_id, lambda: xdf_emg.import_file(
        engine, db, settings, session_id, data, file.filename or "recording.xdf",
        stream or None, _labels(ignore_labels), user.id, _mains(db, session_id)), user)


async def _import(db: Session, settings: Settings, session_id: int, work: Any,
                  user: Any) -> EmgRecording:
    try:
        row: EmgRecording = await asyncio.to_thread(work)
    except NoMontageError as exc:
        conflict("montage", str(exc))
    except ChannelMismatchError as exc:
        _mismatch(["body", "file"], exc)
    except ValueError as exc:
        invalid(["body", "file"], str(exc))
    audit.record(db, user, "create", "emg_recording", row.id,
                 {"source": row.source, "sha256": row.sha256, "filename": row.filename})
    db.commit()
    return row


@router.get("/api/sessions/{session_id}/emg-recordings",
            response_model=list[EmgRecordingOut])
def list_emg_recordings(session_id: SessionId, user: CurrentUser, db: SessionDep
                        ) -> list[EmgRecording]:
    """The session's EMG recordings with their span, trials and quality flags."""
    one_or_404(db, StudySession, session_id, "session")
    return list(db.scalars(select(EmgRecording).where(EmgRecording.session_id == session_id)
                           .order_by(EmgRecording.id)))


@router.get("/api/sessions/{session_id}/emg-recordings/{emg_recording_id}",
            response_model=EmgRecordingOut)
def get_emg_recording(session_id: SessionId, emg_recording_id: EmgRecordingId,
                      user: CurrentUser, db: SessionDep) -> EmgRecording:
    """One recording."""
    row = db.get(EmgRecording, emg_recording_id)
    if row is None or row.session_id != session_id:
        not_found("EMG recording", emg_recording_id)
    return row


# MVC -----------------------------------------------------------------------------------------
@router.get("/api/sessions/{session_id}/mvc-steps", response_model=list[MvcStepOut])
def list_mvc_steps(session_id: SessionId, user: CurrentUser, db: SessionDep) -> list[MvcStep]:
    """The session's MVC steps in order, with the repetitions done."""
    one_or_404(db, StudySession, session_id, "session")
    return mvc.steps(db, session_id)


@router.put("/api/sessions/{session_id}/mvc-steps", response_model=list[MvcStepOut],
            responses=CONFLICT)
def plan_mvc(session_id: SessionId, body: MvcPlanIn, user: CurrentUser, db: SessionDep
             ) -> list[MvcStep]:
    """Plan the session's MVC steps (per muscle and side, repetitions, contraction and
    rest times); 409 once a repetition has run (its markers are data) or without a
    montage; 422 for a muscle/side not in the montage or planned twice."""
    one_or_404(db, StudySession, session_id, "session")
    try:
        mvc.check_plan(body, recordings.session_montage(db, session_id).channels)
        rows = mvc.plan(db, session_id, body)
    except NoMontageError as exc:
        conflict("montage", str(exc))
    except mvc.MvcPlanError as exc:
        invalid(["body", "steps", exc.index, "muscle"], str(exc))
    except mvc.MvcConflictError as exc:
        conflict("steps", str(exc))
    audit.record(db, user, "plan", "mvc_steps", session_id,
                 {"steps": [s.model_dump() for s in body.steps]})
    db.commit()
    return rows


@router.post("/api/sessions/{session_id}/mvc-steps/{mvc_step_id}/events",
             response_model=MvcStepOut, responses=CONFLICT)
def mvc_event(session_id: SessionId, mvc_step_id: MvcStepId, body: MvcEventIn,
              user: CurrentUser, db: SessionDep, lab: LabDep) -> MvcStep:
    """Start or stop the step's next repetition: an `mvc_start` / `mvc_stop` marker
    (stored, shown and sent on LSL like every marker) names muscle, side and
    repetition. 409 for a stop without a start, a start while one runs, or a step
    whose repetitions are all done."""
    step = db.get(MvcStep, mvc_step_id)
    if step is None or step.session_id != session_id:
        not_found("MVC step", mvc_step_id)
    try:
        return mvc.event(db, lab, step, body.event, user.id)
    except mvc.MvcConflictError as exc:
        conflict("event", str(exc))


# A trial's EMG panel ----------------------------------------------------------------------
@router.get("/api/trials/{trial_id}/emg-envelope", response_model=TrialEmgOut,
            responses=CONFLICT)
def trial_emg_envelope(
    trial_id: TrialId, user: CurrentUser, db: SessionDep, engine: EngineDep,
    settings: SettingsDep,
    points: Annotated[int, Query(ge=100, le=20000, description=(
        "most values per channel (the envelope is decimated to fit)"))] = 2000,
) -> TrialEmgOut:
    """The stored EMG's envelope over the trial (the study's processing chain, in volts,
    decimated to at most `points` values), the recording's flags per channel, and the
    trial's lifts with each lift's peak, mean and integral from the full-rate envelope.
    409 saying why for a trial that has not run, that no EMG recording covers or whose
    recording is still being written; 503 with Retry-After while `MAX_CONCURRENT`
    envelopes are being computed. Lifts the recording holds under 90 % of are listed with
    `no_emg`, not measured."""
    from backend.emg.trial_envelope import (
        RETRY_AFTER_S,
        EnvelopeBusyError,
        NoTrialEmgError,
        trial_envelope,
    )

    trial = one_or_404(db, Trial, trial_id, "trial")
    try:
        return trial_envelope(engine, db, settings, trial, points)
    except EnvelopeBusyError as exc:
        raise HTTPException(503, str(exc), headers={"Retry-After": str(RETRY_AFTER_S)}
                            ) from exc
    except NoTrialEmgError as exc:
        conflict("emg", str(exc))
    except ValueError as exc:  # the processing refused the stored data or settings
        conflict("emg_processing", str(exc))
