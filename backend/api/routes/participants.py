"""Participants of a study, and each participant's blinding key."""

from __future__ import annotations

from fastapi import APIRouter, Request

from backend.api.deps import CurrentUser, SessionDep, SettingsDep, SiteDep, access
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    NOT_FOUND,
    one_or_404,
)
from backend.api.params import ParticipantId, StudyId
from backend.db.models import ConditionLabel, Participant, Study
from backend.emg import store
from backend.schemas.participants import (
    ConditionIn,
    ConditionOut,
    ParticipantIn,
    ParticipantOut,
    ParticipantUpdate,
    WithdrawalOut,
)
from backend.study import participants, withdrawal
from backend.study.access import may_unblind

router = APIRouter(tags=["participants"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})


@router.get("/api/studies/{study_id}/participants", response_model=list[ParticipantOut])
def list_participants(study_id: StudyId, site: SiteDep, user: CurrentUser,
                      db: SessionDep) -> list[Participant]:
    """The participants of a study, by code (a site-limited member: that site's)."""
    one_or_404(db, Study, study_id, "study")
    return participants.of_study(db, study_id, site)


@router.post("/api/studies/{study_id}/participants", response_model=ParticipantOut,
             status_code=201, responses=CONFLICT)
def create_participant(study_id: StudyId, body: ParticipantIn, site: SiteDep,
                       user: CurrentUser, db: SessionDep) -> Participant:
    """Enrol a participant under a pseudonymous code; 409 if the code exists in the
    study. A site-limited member enrols into their own site only."""
    one_or_404(db, Study, study_id, "study")
    return participants.enrol(db, user, study_id, body, site)


@router.get("/api/participants/{participant_id}", response_model=ParticipantOut)
def get_participant(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
                    ) -> Participant:
    """One participant."""
    return one_or_404(db, Participant, participant_id, "participant")


@router.patch("/api/participants/{participant_id}", response_model=ParticipantOut,
              responses=CONFLICT)
def update_participant(participant_id: ParticipantId, body: ParticipantUpdate,
                       site: SiteDep, user: CurrentUser, db: SessionDep) -> Participant:
    """Correct a participant's record; `null` clears an optional field."""
    p = one_or_404(db, Participant, participant_id, "participant")
    return participants.correct(db, user, p, body, site)


@router.get("/api/participants/{participant_id}/conditions",
            response_model=list[ConditionOut])
def list_conditions(participant_id: ParticipantId, request: Request, user: CurrentUser,
                    db: SessionDep) -> list[ConditionOut]:
    """The participant's blinded labels; the blinding key (which controller each label
    stands for) only for the study's owners, `null` for everyone else."""
    one_or_404(db, Participant, participant_id, "participant")
    rows = participants.conditions_of(db, participant_id)
    unblind = may_unblind(request.state)
    return [ConditionOut.model_validate(c).model_copy(
        update={} if unblind else {"controller": None}) for c in rows]


@router.post("/api/participants/{participant_id}/conditions", response_model=ConditionOut,
             status_code=201, responses=CONFLICT)
def add_condition(participant_id: ParticipantId, body: ConditionIn, user: CurrentUser,
                  db: SessionDep) -> ConditionLabel:
    """Blind a controller behind a label; 409 if the label or controller already has an
    entry for this participant (a key never changes once forms may use it)."""
    one_or_404(db, Participant, participant_id, "participant")
    return participants.add_condition(db, user, participant_id, body)


@router.post("/api/participants/{participant_id}/withdraw", response_model=WithdrawalOut,
             openapi_extra=access("owner"))
def withdraw(participant_id: ParticipantId, user: CurrentUser, db: SessionDep,
             settings: SettingsDep) -> WithdrawalOut:
    """A participant withdraws: their data is erased, or (when the study's protocol
    says "exclude") kept, marked withdrawn and left out of results and exports. The
    audit entry names the participant id only, never the erased data."""
    p = one_or_404(db, Participant, participant_id, "participant")
    outcome = withdrawal.withdraw(db, p, user, store.emg_folder(settings))
    return WithdrawalOut(participant_id=participant_id, outcome=outcome)
