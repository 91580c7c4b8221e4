"""The lab: event markers, LSL marker streams of other software, XDF attachments, and the
study's BIDS-motion export. Every route sits under the study, session or trial it
concerns, so a study's access rules apply to it."""

from __future__ import annotations

import asyncio
import io
import zipfile
from pathlib import Path as PathType
from typing import Annotated

from fastapi import APIRouter, File, HTTPException, Path, Request, UploadFile
from fastapi.responses import Response
from sqlalchemy import Engine
from sqlalchemy.orm import Session

from backend.analysis import markers as analysis_markers
from backend.api.deps import (
    CurrentUser,
    EngineDep,
    LabDep,
    RuntimeDep,
    SessionDep,
    SettingsDep,
    SiteDep,
    access,
)
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    NOT_FOUND,
    conflict,
    invalid,
    one_or_404,
)
from backend.api.params import MAX_ID, SessionId, StudyId
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker, MarkerStream, XdfAttachment
from backend.db.models import Study, StudySession
from backend.db.sessions import study_of_session
from backend.emg import store as emg_store
from backend.lab import bids_export, markers, session_records, xdf_import
from backend.lab.hub import Lab
from backend.schemas.lab import (
    LslStreamOut,
    MarkerIn,
    MarkerLabels,
    MarkerOut,
    MarkerStreamIn,
    MarkerStreamOut,
    XdfAttachmentOut,
)
from backend.study import studies
from backend.study.access import may_unblind

router = APIRouter(tags=["lab"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]
SubscriptionId = Annotated[int, Path(ge=1, le=MAX_ID, description="subscription id")]
AttachmentId = Annotated[int, Path(ge=1, le=MAX_ID, description="XDF attachment id")]


# Marker labels of a study ------------------------------------------------------------------
@router.get("/api/studies/{study_id}/marker-labels", response_model=MarkerLabels)
def get_marker_labels(study_id: StudyId, user: CurrentUser, db: SessionDep) -> MarkerLabels:
    """The study's marker buttons, in hotkey order (1-9)."""
    one_or_404(db, Study, study_id, "study")
    return MarkerLabels(labels=markers.labels(db, study_id))


@router.put("/api/studies/{study_id}/marker-labels", response_model=MarkerLabels)
def put_marker_labels(study_id: StudyId, body: MarkerLabels, user: CurrentUser,
                      db: SessionDep) -> MarkerLabels:
    """Replace the study's marker buttons."""
    one_or_404(db, Study, study_id, "study")
    session_records.set_marker_labels(db, user, study_id, body.labels)
    return body


@router.get("/api/sessions/{session_id}/marker-labels", response_model=MarkerLabels)
def session_marker_labels(session_id: SessionId, user: CurrentUser, db: SessionDep
                          ) -> MarkerLabels:
    """The marker buttons of the study the session belongs to."""
    one_or_404(db, StudySession, session_id, "session")
    study_id = study_of_session(db, session_id)
    return MarkerLabels(labels=markers.labels(db, study_id) if study_id is not None else [])


# Markers ------------------------------------------------------------------------------------
@router.post("/api/sessions/{session_id}/markers", response_model=MarkerOut, status_code=201,
             responses=CONFLICT)
def add_marker(session_id: SessionId, body: MarkerIn, user: CurrentUser, db: SessionDep,
               lab: LabDep) -> Marker:
    """An event marker now: stamped with the newest tick, stored with the session's
    running trial (if that tick is the trial's), drawn on the consoles and sent on the
    LSL marker stream. 409 while a trial runs whose ticks have ended (a timed trial
    past its duration: stop it first)."""
    one_or_404(db, StudySession, session_id, "session")
    return lab.console_marker(db, session_id, body.label, body.note, user.id)


@router.get("/api/sessions/{session_id}/markers", response_model=list[MarkerOut])
def session_markers(session_id: SessionId, user: CurrentUser, db: SessionDep
                    ) -> list[Marker]:
    """The session's markers in the order they were stored."""
    one_or_404(db, StudySession, session_id, "session")
    return session_records.session_markers(db, session_id)


@router.get("/api/trials/{trial_id}/markers", response_model=list[MarkerOut])
def trial_markers(trial_id: TrialId, user: CurrentUser, db: SessionDep) -> list[Marker]:
    """A trial's markers in tick-time order (`t` is on the trial's tick time axis)."""
    one_or_404(db, Trial, trial_id, "trial")
    return analysis_markers.trial_markers(db, trial_id)


# LSL marker streams of other software -----------------------------------------------------
def _lsl_on(lab: Lab) -> None:
    if not lab.enabled:
        conflict("lsl", "the Lab Streaming Layer is switched off (EXOSTUDY_LSL_ENABLED)")


@router.get("/api/sessions/{session_id}/lsl-streams", response_model=list[LslStreamOut],
            responses=CONFLICT)
async def visible_streams(session_id: SessionId, user: CurrentUser, db: SessionDep,
                          lab: LabDep) -> list[LslStreamOut]:
    """The LSL streams visible on the network now (marker streams first)."""
    from backend.lab.marker_inlet import visible_streams as resolve

    one_or_404(db, StudySession, session_id, "session")
    _lsl_on(lab)
    found = await asyncio.to_thread(resolve, 1.0)
    own = f"exostudy-{lab.outlets.name}-"
    return [LslStreamOut(name=s.name, type=s.type, source_id=s.source_id,
                         hostname=s.hostname, channel_count=s.channel_count,
                         nominal_srate=s.nominal_srate, own=s.source_id.startswith(own))
            for s in found]


def _sub_out(lab: Lab, sub: MarkerStream) -> MarkerStreamOut:
    out = MarkerStreamOut.model_validate(sub)
    inlet = lab.inlets.get(sub.id)
    out.connected = bool(inlet is not None and inlet.connected)
    return out


@router.get("/api/sessions/{session_id}/marker-streams",
            response_model=list[MarkerStreamOut])
def list_marker_streams(session_id: SessionId, user: CurrentUser, db: SessionDep,
                        lab: LabDep) -> list[MarkerStreamOut]:
    """The session's subscriptions to other software's marker streams."""
    one_or_404(db, StudySession, session_id, "session")
    return [_sub_out(lab, s) for s in session_records.subscriptions(db, session_id)]


@router.post("/api/sessions/{session_id}/marker-streams", response_model=MarkerStreamOut,
             status_code=201, responses=CONFLICT)
def subscribe(session_id: SessionId, body: MarkerStreamIn, user: CurrentUser,
              db: SessionDep, lab: LabDep) -> MarkerStreamOut:
    """Store this marker stream's markers with the session (and its running trial) from
    now on. One session at a time listens to a given stream."""
    one_or_404(db, StudySession, session_id, "session")
    _lsl_on(lab)
    sub = session_records.subscribe(db, user, session_id, body)
    lab.subscribe(sub.id, sub.name, sub.source_id)
    return _sub_out(lab, sub)


@router.delete("/api/sessions/{session_id}/marker-streams/{subscription_id}",
               response_model=MarkerStreamOut)
def unsubscribe(session_id: SessionId, subscription_id: SubscriptionId, user: CurrentUser,
                db: SessionDep, lab: LabDep) -> MarkerStreamOut:
    """Stop storing the stream's markers (those stored stay)."""
    sub = session_records.subscription(db, session_id, subscription_id)
    lab.unsubscribe(sub.id)
    session_records.end_subscription(db, user, sub)
    return _sub_out(lab, sub)


# XDF attachments -----------------------------------------------------------------------------
@router.post("/api/sessions/{session_id}/xdf", response_model=XdfAttachmentOut,
             status_code=201, responses={413: {"description": "the file is too large"}})
async def attach_xdf(session_id: SessionId, engine: EngineDep, user: CurrentUser,
                     db: SessionDep, settings: SettingsDep,
                     file: Annotated[UploadFile, File(description="a LabRecorder .xdf file")],
                     ) -> XdfAttachment:
    """Attach a LabRecorder XDF file (at most `max_upload_bytes`): kept whole, its
    streams aligned with the session's ticks on the LSL clock, and for each the trials
    it covers. ExoStudy's own reader decodes it in a child process within the
    `xdf_max_*` settings and `xdf_parse_seconds`; a malformed file, one that declares
    more than it holds or more than those limits, or an ExoStudy tick stream with
    unusable fields is refused (422, saying what and where)."""
    one_or_404(db, StudySession, session_id, "session")
    limit = settings.max_upload_bytes
    data = await file.read(limit + 1)
    if len(data) > limit:  # the body limit stops it first; a file part cannot be larger
        raise HTTPException(413, f"file: larger than {limit} bytes")
    try:
        # Reads the session's ticks: off the event loop (the session is used by this
        # request only, one step at a time).
        summary = await asyncio.to_thread(xdf_import.import_file, engine, db, session_id,
                                          data, settings)
    except ValueError as exc:
        invalid(["body", "file"], str(exc))
    return session_records.attach_xdf(db, user, session_id,
                                      file.filename or "recording.xdf", data, summary)


@router.get("/api/sessions/{session_id}/xdf", response_model=list[XdfAttachmentOut])
def list_xdf(session_id: SessionId, user: CurrentUser, db: SessionDep) -> list[XdfAttachment]:
    """The session's XDF files with their aligned streams."""
    one_or_404(db, StudySession, session_id, "session")
    return session_records.attachments(db, session_id)


@router.get("/api/sessions/{session_id}/xdf/{attachment_id}/file", response_class=Response,
            responses={200: {"content": {"application/octet-stream": {}},
                             "description": "the XDF file as attached"}})
def download_xdf(session_id: SessionId, attachment_id: AttachmentId, user: CurrentUser,
                 db: SessionDep) -> Response:
    """The attached file, byte for byte."""
    att = session_records.attachment(db, session_id, attachment_id)
    return Response(att.content, media_type="application/octet-stream", headers={
        "Content-Disposition": f'attachment; filename="{att.id}.xdf"'})


# BIDS ----------------------------------------------------------------------------------------
def bids_zip(engine: Engine, db: Session, study_id: int, site: str | None,
             unblind: bool = False, emg_dir: PathType | None = None) -> bytes:
    """The study's BIDS dataset as a zip whose top folder is the dataset."""
    buf = io.BytesIO()
    root = f"study-{study_id}-bids/"
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for path, data in bids_export.dataset_files(engine, db, study_id, site, unblind,
                                                            emg_dir):
            zf.writestr(root + path, data)
    return buf.getvalue()


@router.get("/api/studies/{study_id}/export.bids.zip", response_class=Response, responses={
    200: {"content": {"application/zip": {}},
          "description": "a BIDS dataset (motion modality) of the study"}, **CONFLICT},
    openapi_extra=access("experimenter"))
def export_bids(study_id: StudyId, engine: EngineDep, site: SiteDep, user: CurrentUser,
                db: SessionDep, runtime: RuntimeDep, request: Request,
                settings: SettingsDep) -> Response:
    """The study as a BIDS-motion dataset: participants, one motion file per trial with
    channels and events (lifts, locks, markers), questionnaires as phenotype files,
    attached XDF files as source data. De-identified fields only. Controllers are
    named for the study's owner only; anyone else gets blinded labels (`acq-A`). 409
    if no trial of the study has ticks yet (a BIDS motion dataset needs one)."""
    one_or_404(db, Study, study_id, "study")
    runtime.recorder.flush()
    try:
        data = bids_zip(engine, db, study_id, site, may_unblind(request.state),
                        emg_store.emg_folder(settings))
    except bids_export.NothingToExportError as exc:
        conflict("study", str(exc))
    except emg_store.EmgStoreError as exc:
        conflict("emg", f"an EMG recording file of the study does not read back: {exc}")
    studies.record_export(db, user, study_id, "export", {"format": "bids", "bytes": len(data)})
    return Response(data, media_type="application/zip", headers={
        "Content-Disposition": f'attachment; filename="study-{study_id}-bids.zip"'})
