"""Who may do what: global roles, study roles, sites, and the study behind an id.

Global roles: `admin` (manages accounts, acts as owner of every study) and `member`.
Study roles, each including the ones below it: `owner` (unblinding, export, deletion,
membership), `experimenter` (records, edits, runs the device) and `viewer` (reads).
A membership may be limited to one site: the member then sees only that site's
participants (REDCap's data access groups).

The API's single authorisation dependency (`backend.api.deps.authorize`) uses this
module to find the study an id in the path belongs to and the caller's role in it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.evidence_tables import (
    Job,
    LiftSegment,
    ModelSetRecord,
    Recording,
    Trial,
    TrialSegment,
    UtilitySetRecord,
)
from backend.db.models import Participant, Study, StudyMember, StudySession, User
from backend.db.personalisation import PriorSetRecord

StudyRole = Literal["viewer", "experimenter", "owner"]
STUDY_ROLES: tuple[StudyRole, ...] = ("viewer", "experimenter", "owner")
_RANK: dict[str, int] = {role: i for i, role in enumerate(STUDY_ROLES)}


def at_least(role: str | None, needed: StudyRole) -> bool:
    """True if `role` includes `needed` (owner > experimenter > viewer)."""
    return role is not None and _RANK.get(role, -1) >= _RANK[needed]


@dataclass(frozen=True)
class Grant:
    """The caller's standing in one study: role and the site it is limited to."""

    study_id: int
    role: StudyRole
    site: str | None  # None: every site


def grant(db: Session, user: User, study_id: int) -> Grant | None:
    """The user's role in the study: admins own every study; the creator owns it unless
    a membership says otherwise; otherwise the membership, or None."""
    if user.role == "admin":
        return Grant(study_id, "owner", None)
    member = db.scalars(select(StudyMember).where(
        StudyMember.study_id == study_id, StudyMember.user_id == user.id)).first()
    if member is not None and member.role in _RANK:
        role: StudyRole = STUDY_ROLES[_RANK[member.role]]
        return Grant(study_id, role, member.site)
    study = db.get(Study, study_id)
    if study is not None and study.created_by == user.id:
        return Grant(study_id, "owner", None)
    return None


def visible_study_ids(db: Session, user: User) -> set[int] | None:
    """The studies a user can see (None: all of them, for an admin)."""
    if user.role == "admin":
        return None
    ids = set(db.scalars(select(StudyMember.study_id).where(StudyMember.user_id == user.id)))
    ids |= set(db.scalars(select(Study.id).where(Study.created_by == user.id)))
    return ids


def best_study_role(db: Session, user: User) -> StudyRole | None:
    """The highest role the user holds in any study (admins: owner)."""
    if user.role == "admin":
        return "owner"
    roles = set(db.scalars(select(StudyMember.role).where(StudyMember.user_id == user.id)))
    if db.scalars(select(Study.id).where(Study.created_by == user.id)).first() is not None:
        roles.add("owner")
    ranked = [r for r in STUDY_ROLES if r in roles]
    return ranked[-1] if ranked else None


@dataclass(frozen=True)
class Target:
    """The study (and participant, if any) an id in a path belongs to; `study_id` None
    for a row that exists but belongs to no study (a virtual cohort's job)."""

    study_id: int | None
    participant_id: int | None = None


def _of_participant(db: Session, pid: int | None) -> Target | None:
    p = db.get(Participant, pid) if pid is not None else None
    return Target(p.study_id, p.id) if p is not None else None


def _of_session(db: Session, sid: int | None) -> Target | None:
    s = db.get(StudySession, sid) if sid is not None else None
    return _of_participant(db, s.participant_id) if s is not None else None


def _of_recording(db: Session, rid: int | None) -> Target | None:
    r = db.get(Recording, rid) if rid is not None else None
    return _of_session(db, r.session_id) if r is not None else None


def _of_trial(db: Session, tid: int | None) -> Target | None:
    t = db.get(Trial, tid) if tid is not None else None
    return _of_session(db, t.session_id) if t is not None else None


def _of_study(db: Session, sid: int) -> Target | None:
    return Target(sid) if db.get(Study, sid) is not None else None


def _of_model_set(db: Session, mid: int) -> Target | None:
    m = db.get(ModelSetRecord, mid)
    # A personal set is its wearer's: site limits apply to it as to them.
    return Target(m.study_id, m.participant_id) if m is not None else None


def _of_prior_set(db: Session, pid: int) -> Target | None:
    p = db.get(PriorSetRecord, pid)
    return Target(p.study_id, p.participant_id) if p is not None else None


def _of_utility_set(db: Session, uid: int) -> Target | None:
    u = db.get(UtilitySetRecord, uid)
    return Target(u.study_id) if u is not None else None


def _of_segment(db: Session, sid: int) -> Target | None:
    s = db.get(LiftSegment, sid)
    return _of_recording(db, s.recording_id) if s is not None else None


def _of_trial_segment(db: Session, sid: int) -> Target | None:
    s = db.get(TrialSegment, sid)
    return _of_trial(db, s.trial_id) if s is not None else None


def _of_job(db: Session, jid: int) -> Target | None:
    job = db.get(Job, jid)
    if job is None:
        return None
    if job.kind in ("fit_model_set", "fit_personal_model_set"):
        return _of_model_set(db, job.target_id)
    if job.kind == "compute_utilities":
        return _of_utility_set(db, job.target_id)
    # A virtual cohort (or any later kind) belongs to no study: the job exists, and is
    # checked as a path without a study (the role somewhere).
    return Target(None)


#: How each path parameter that names a stored row leads to its study. A new route
#: whose path has one of these parameters is authorised against that study with no
#: further code; a new kind of id needs one line here.
RESOLVERS = {
    "study_id": _of_study,
    "participant_id": _of_participant,
    "session_id": _of_session,
    "recording_id": _of_recording,
    "trial_id": _of_trial,
    "model_set_id": _of_model_set,
    "prior_set_id": _of_prior_set,
    "utility_set_id": _of_utility_set,
    "segment_id": _of_segment,
    "trial_segment_id": _of_trial_segment,
    "job_id": _of_job,
}


def running_study(db: Session) -> int | None:
    """The study whose trial or recording is running now, if any: the device is
    someone's to control only while their study uses it."""
    trial = db.scalars(select(Trial).where(Trial.status == "running")).first()
    if trial is not None:
        t = _of_trial(db, trial.id)
        return t.study_id if t else None
    rec = db.scalars(select(Recording).where(Recording.status == "recording")).first()
    if rec is not None:
        t = _of_recording(db, rec.id)
        return t.study_id if t else None
    return None


def may_unblind(state: object) -> bool:
    """True if the request's grant (set by the access check on `request.state`) is the
    owner's: only owners (and admins) see which controller a blinded label stands for."""
    g = getattr(state, "grant", None)
    return isinstance(g, Grant) and g.role == "owner"


def site_allows(db: Session, g: Grant, participant_id: int | None) -> bool:
    """False when a site-limited member reaches a participant of another site."""
    if g.site is None or participant_id is None:
        return True
    p = db.get(Participant, participant_id)
    return p is not None and p.site == g.site
