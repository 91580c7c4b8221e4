"""What a study sets up for EMG before anything is recorded: its montage (versioned, never
changed in place, since a recording keeps the version its channels were mapped by) and
its analysis settings (one row, defaults until set).

The queries and writes behind the montage and settings routes; refusals are
`backend.core.errors`. Both writes race with concurrent requests for a unique key, so
each retries a few times before it is a conflict rather than an error.
"""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError
from backend.db import audit
from backend.db.emg import EmgAnalysisSettings, EmgMontage, EmgRecording, EmgStream
from backend.db.models import User
from backend.db.sessions import study_of_session
from backend.schemas.emg import EmgSettingsIn, MontageIn
from controller.emg.montage import normalise_label
from controller.emg.processing import EmgProcessing, EmgSettingsError

#: Tries of a write that concurrent requests race for before it is a conflict.
WRITE_ATTEMPTS = 5
#: Mains frequency of a study whose settings are not set yet.
DEFAULT_MAINS_HZ = 50


# Montage ------------------------------------------------------------------------------------
def montage_versions(db: Session, study_id: int) -> list[EmgMontage]:
    """Every version of the study's montage, oldest first."""
    return list(db.scalars(select(EmgMontage).where(EmgMontage.study_id == study_id)
                           .order_by(EmgMontage.version)))


def check_montage(body: MontageIn) -> None:
    """Repeated labels or (muscle, side): `InvalidError` naming each repeated entry."""
    problems: list[tuple[list[str | int], str]] = []
    labels: dict[str, int] = {}
    pairs: dict[tuple[str, str], int] = {}
    for i, c in enumerate(body.channels):
        key = normalise_label(c.label)
        if not key:
            problems.append((["body", "channels", i, "label"], "a channel label needs a "
                             "letter or digit"))
        elif (first := labels.setdefault(key, i)) != i:
            problems.append((["body", "channels", i, "label"], f"duplicate channel: label "
                             f"{c.label!r} is also channel {first}"))
        if (first := pairs.setdefault((c.muscle, c.side), i)) != i:
            problems.append((["body", "channels", i, "muscle"], f"duplicate channel: "
                             f"{c.side} {c.muscle} is also channel {first}"))
    if problems:
        raise InvalidError(problems)


def save_montage(db: Session, user: User, study_id: int, body: MontageIn) -> EmgMontage:
    """Check the montage and store it as the study's next version; commits."""
    check_montage(body)
    # Concurrent PUTs race for the next version number (unique per study): the loser
    # takes the one after; a conflict only if it keeps losing.
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
        return row
    raise ConflictError("montage", "other montage versions were being saved at the same "
                        "time; send it again")


def delete_montage(db: Session, user: User, study_id: int) -> list[EmgMontage]:
    """Remove every version of the study's montage and return them; a conflict once a
    recording or a subscription uses one (a recording's channels must stay mapped)."""
    rows = list(db.scalars(select(EmgMontage).where(EmgMontage.study_id == study_id)))
    ids = [r.id for r in rows] or [-1]
    used = db.scalar(select(func.count()).select_from(EmgRecording)
                     .where(EmgRecording.montage_id.in_(ids)))
    subs = db.scalar(select(func.count()).select_from(EmgStream)
                     .where(EmgStream.montage_id.in_(ids)))
    if used or subs:
        raise ConflictError("montage", f"{used} recordings and {subs} EMG subscriptions use "
                            "the study's montage; change it with PUT (a new version) instead")
    for r in rows:
        db.delete(r)
    audit.record(db, user, "delete", "emg_montage", study_id, {"versions": len(rows)})
    db.commit()
    return rows


# Analysis settings --------------------------------------------------------------------------
def analysis_settings(db: Session, study_id: int) -> EmgAnalysisSettings | None:
    """The study's stored settings; None until first set (the defaults apply)."""
    return db.get(EmgAnalysisSettings, study_id)


def save_analysis_settings(db: Session, user: User, study_id: int, body: EmgSettingsIn
                           ) -> EmgAnalysisSettings:
    """Store the study's processing chain (every parameter, defaults filled in),
    normalisation and mains frequency; `InvalidError` for a chain the processing
    refuses. Commits."""
    data = dict(body.processing)
    if body.normalisation is not None:
        data["normalisation"] = body.normalisation
    try:
        proc = EmgProcessing.from_dict(data)
    except (EmgSettingsError, TypeError) as exc:
        raise InvalidError.at(["body", "processing"], str(exc)) from exc
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
        return row
    raise ConflictError("emg_settings", "the settings were being saved by another request "
                        "at the same time; send them again")


def session_mains_hz(db: Session, session_id: int) -> int:
    """The mains frequency of the session's study (the default until set)."""
    sid = study_of_session(db, session_id)
    row = db.get(EmgAnalysisSettings, sid) if sid is not None else None
    return row.mains_hz if row is not None else DEFAULT_MAINS_HZ
