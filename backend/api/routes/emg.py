"""Muscle activity: a study's montage and EMG analysis settings, a session's EMG from LSL
and from EDF/BDF and XDF files, its recordings, and its MVC steps."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Annotated, NoReturn

from fastapi import APIRouter, File, Form, HTTPException, Path, Query, UploadFile

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
    not_found,
    one_or_404,
)
from backend.api.params import MAX_ID, SessionId, StudyId
from backend.db.emg import (
    EmgAnalysisSettings,
    EmgMontage,
    EmgRecording,
    EmgStream,
    MvcStep,
)
from backend.db.evidence_tables import Trial
from backend.db.models import Study, StudySession, User
from backend.emg import edf_import, live, mvc, recordings, study_setup, subscriptions
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
from controller.emg.processing import EmgProcessing

router = APIRouter(tags=["emg"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})

EmgStreamId = Annotated[int, Path(ge=1, le=MAX_ID, description="EMG subscription id")]
EmgRecordingId = Annotated[int, Path(ge=1, le=MAX_ID, description="EMG recording id")]
MvcStepId = Annotated[int, Path(ge=1, le=MAX_ID, description="MVC step id")]
TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


# Montage ------------------------------------------------------------------------------------
def _montage_out(row: EmgMontage) -> MontageOut:
    return MontageOut(id=row.id, study_id=row.study_id, version=row.version,
                      created_at=row.created_at, placement_scheme=row.placement_scheme,
                      channels=row.channels)  # type: ignore[arg-type]


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
    return [_montage_out(r) for r in study_setup.montage_versions(db, study_id)]


@router.put("/api/studies/{study_id}/emg-montage", response_model=MontageOut,
            responses=CONFLICT)
def put_montage(study_id: StudyId, body: MontageIn, user: CurrentUser,
                db: SessionDep) -> MontageOut:
    """A new version of the study's montage (older versions stay: recordings keep the
    version their channels were mapped by). Unknown muscles and repeated channels are
    a 422 naming the field."""
    one_or_404(db, Study, study_id, "study")
    return _montage_out(study_setup.save_montage(db, user, study_id, body))


@router.delete("/api/studies/{study_id}/emg-montage", response_model=list[MontageOut],
               responses=CONFLICT)
def delete_montage(study_id: StudyId, user: CurrentUser, db: SessionDep) -> list[MontageOut]:
    """Remove the study's montage (every version); 409 once a recording or a
    subscription uses one (a recording's channels must stay mapped)."""
    one_or_404(db, Study, study_id, "study")
    return [_montage_out(r) for r in study_setup.delete_montage(db, user, study_id)]


# Analysis settings --------------------------------------------------------------------------
def _settings_out(row: EmgAnalysisSettings | None) -> EmgSettingsOut:
    proc = EmgProcessing.from_dict(row.processing) if row is not None else EmgProcessing()
    return EmgSettingsOut(processing=proc.to_dict(), normalisation=proc.normalisation,
                          mains_hz=row.mains_hz if row is not None
                          else study_setup.DEFAULT_MAINS_HZ)


@router.get("/api/studies/{study_id}/emg-settings", response_model=EmgSettingsOut)
def get_emg_settings(study_id: StudyId, user: CurrentUser, db: SessionDep) -> EmgSettingsOut:
    """The study's EMG processing chain and normalisation (defaults until set)."""
    one_or_404(db, Study, study_id, "study")
    return _settings_out(study_setup.analysis_settings(db, study_id))


@router.put("/api/studies/{study_id}/emg-settings", response_model=EmgSettingsOut,
            responses=CONFLICT)
def put_emg_settings(study_id: StudyId, body: EmgSettingsIn, user: CurrentUser,
                     db: SessionDep) -> EmgSettingsOut:
    """Set the study's EMG processing chain and normalisation method; every parameter is
    stored (defaults filled in) and written into results and exports."""
    one_or_404(db, Study, study_id, "study")
    return _settings_out(study_setup.save_analysis_settings(db, user, study_id, body))


# Live EMG from LSL --------------------------------------------------------------------------
def _stream_out(emg: EmgLab, sub: EmgStream) -> EmgStreamOut:
    out = EmgStreamOut.model_validate(sub)
    inlet = emg.inlets.get(sub.id)
    out.connected = bool(inlet is not None and inlet.connected)
    out.last_time = inlet.last_time if inlet is not None else None
    return out


def _mismatch(loc: list[str | int], exc: ChannelMismatchError) -> NoReturn:
    raise HTTPException(422, [{"loc": loc, "msg": str(exc), "type": "value_error",
                               "unmatched_labels": exc.unmatched,
                               "missing_labels": exc.missing,
                               "expected_labels": exc.expected}])


@router.get("/api/sessions/{session_id}/emg-streams", response_model=list[EmgStreamOut])
def list_emg_streams(session_id: SessionId, user: CurrentUser, db: SessionDep,
                     emg: EmgLabDep) -> list[EmgStreamOut]:
    """The session's EMG stream subscriptions."""
    one_or_404(db, StudySession, session_id, "session")
    return [_stream_out(emg, s) for s in subscriptions.session_streams(db, session_id)]


@router.post("/api/sessions/{session_id}/emg-streams", response_model=EmgStreamOut,
             status_code=201, responses=CONFLICT)
async def subscribe_emg(session_id: SessionId, body: EmgStreamIn, user: CurrentUser,
                        db: SessionDep, emg: EmgLabDep) -> EmgStreamOut:
    """Record this LSL EMG stream with the session from now on, in chunks to the EMG
    folder, on this server's LSL clock (clock correction). The stream must be visible
    (409 otherwise), of type EMG, in volts (V, mV, uV), and its channel labels must match
    the study's montage (422 listing unmatched and expected labels); nothing is stored
    otherwise."""
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
    # The stream's identity is what it resolved to (its source id, else its name).
    sub = subscriptions.add(db, user, session_id, body, montage, str(info.name()),
                            str(info.source_id()))
    emg.subscribe(sub.id)
    return _stream_out(emg, sub)


@router.delete("/api/sessions/{session_id}/emg-streams/{emg_stream_id}",
               response_model=EmgStreamOut)
async def unsubscribe_emg(session_id: SessionId, emg_stream_id: EmgStreamId,
                          user: CurrentUser, db: SessionDep, emg: EmgLabDep
                          ) -> EmgStreamOut:
    """Stop recording the stream; the recording so far is finished and kept."""
    sub = subscriptions.session_stream(db, session_id, emg_stream_id)
    await asyncio.to_thread(emg.unsubscribe, sub.id)
    return _stream_out(emg, subscriptions.deactivate(db, user, sub))


# Files -------------------------------------------------------------------------------------
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
    return await _import(db, user, lambda: edf_import.import_file(
        db, settings, session_id, data, file.filename or "recording.edf", how,
        _labels(ignore_labels), user.id, study_setup.session_mains_hz(db, session_id)))


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
    return await _import(db, user, lambda: xdf_emg.import_file(
        engine, db, settings, session_id, data, file.filename or "recording.xdf",
        stream or None, _labels(ignore_labels), user.id,
        study_setup.session_mains_hz(db, session_id)))


async def _import(db: SessionDep, user: User, work: Callable[[], EmgRecording]
                  ) -> EmgRecording:
    """Run an import off the event loop and audit it; its refusals as 409 or 422."""
    try:
        row = await asyncio.to_thread(work)
    except NoMontageError as exc:
        conflict("montage", str(exc))
    except ChannelMismatchError as exc:
        _mismatch(["body", "file"], exc)
    except ValueError as exc:
        invalid(["body", "file"], str(exc))
    return recordings.record_import(db, user, row)


@router.get("/api/sessions/{session_id}/emg-recordings",
            response_model=list[EmgRecordingOut])
def list_emg_recordings(session_id: SessionId, user: CurrentUser, db: SessionDep
                        ) -> list[EmgRecording]:
    """The session's EMG recordings with their span, trials and quality flags."""
    one_or_404(db, StudySession, session_id, "session")
    return recordings.session_recordings(db, session_id)


@router.get("/api/sessions/{session_id}/emg-recordings/{emg_recording_id}",
            response_model=EmgRecordingOut)
def get_emg_recording(session_id: SessionId, emg_recording_id: EmgRecordingId,
                      user: CurrentUser, db: SessionDep) -> EmgRecording:
    """One recording."""
    return recordings.session_recording(db, session_id, emg_recording_id)


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
        return mvc.replan(db, user, session_id, body)
    except NoMontageError as exc:
        conflict("montage", str(exc))
    except mvc.MvcPlanError as exc:
        invalid(["body", "steps", exc.index, "muscle"], str(exc))
    except mvc.MvcConflictError as exc:
        conflict("steps", str(exc))


@router.post("/api/sessions/{session_id}/mvc-steps/{mvc_step_id}/events",
             response_model=MvcStepOut, responses=CONFLICT)
def mvc_event(session_id: SessionId, mvc_step_id: MvcStepId, body: MvcEventIn,
              user: CurrentUser, db: SessionDep, lab: LabDep) -> MvcStep:
    """Start or stop the step's next repetition: an `mvc_start` / `mvc_stop` marker
    (stored, shown and sent on LSL like every marker) names muscle, side and
    repetition. 409 for a stop without a start, a start while one runs, or a step
    whose repetitions are all done."""
    step = mvc.step_of(db, session_id, mvc_step_id)
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
