"""Personal model sets and prior sets of a participant (issue 30): fitted and learned
with their provenance, versioned, listed per participant and per study."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path

from backend.analysis import personal_model_sets, prior_sets
from backend.api.deps import CurrentUser, EngineDep, JobsDep, SessionDep, SessionFactoryDep
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND
from backend.api.params import MAX_ID, ParticipantId, StudyId
from backend.db.evidence_tables import ModelSetRecord
from backend.db.personalisation import PriorSetRecord
from backend.schemas.personalisation import (
    PersonalModelSetIn,
    PersonalModelSetOut,
    PriorSetIn,
    PriorSetOut,
)

router = APIRouter(tags=["personalisation"], responses={**AUTH_RESPONSES, **NOT_FOUND})

PriorSetId = Annotated[int, Path(ge=1, le=MAX_ID, description="prior set id")]


@router.post("/api/participants/{participant_id}/personal-model-sets",
             response_model=PersonalModelSetOut, status_code=202, responses=CONFLICT)
def fit_personal_model_set(participant_id: ParticipantId, body: PersonalModelSetIn,
                           engine: EngineDep, sessions: SessionFactoryDep, jobs: JobsDep,
                           user: CurrentUser, db: SessionDep) -> PersonalModelSetOut:
    """Fit the participant's personal model set from their labelled demonstrations
    (the population set adapted to them, or fitted from them alone). Returns at once
    with the job id; poll `GET /api/jobs/{job_id}`; the set is a model set
    (`/api/model-sets/{id}`, `/document`) of kind `personal`."""
    return personal_model_sets.fit_personal_set(db, engine, sessions, jobs, user,
                                                participant_id, body)


@router.get("/api/participants/{participant_id}/personal-model-sets",
            response_model=list[PersonalModelSetOut])
def list_personal_model_sets(participant_id: ParticipantId, user: CurrentUser,
                             db: SessionDep) -> list[ModelSetRecord]:
    """The participant's personal model sets, oldest first."""
    return personal_model_sets.participant_sets(db, participant_id)


@router.get("/api/studies/{study_id}/personal-model-sets",
            response_model=list[PersonalModelSetOut])
def list_study_personal_model_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                                   ) -> list[ModelSetRecord]:
    """Every personal model set of the study's participants, oldest first."""
    return personal_model_sets.study_sets(db, study_id)


@router.post("/api/participants/{participant_id}/prior-sets", response_model=PriorSetOut,
             status_code=201, responses=CONFLICT)
def learn_prior_set(participant_id: ParticipantId, body: PriorSetIn,
                    user: CurrentUser, db: SessionDep) -> PriorSetRecord:
    """A new version of the participant's priors: learned from confirmed motions
    (`dirichlet`) or unconfirmed use (`label-shift-em`) and projected onto the safety
    bound of the utility set; the equal priors; or imported `values`, refused (422)
    outside that bound."""
    return prior_sets.learn_prior_set(db, user, participant_id, body)


@router.get("/api/participants/{participant_id}/prior-sets", response_model=list[PriorSetOut])
def list_prior_sets(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
                    ) -> list[PriorSetRecord]:
    """The participant's prior sets, by version."""
    return prior_sets.participant_prior_sets(db, participant_id)


@router.get("/api/studies/{study_id}/prior-sets", response_model=list[PriorSetOut])
def list_study_prior_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                          ) -> list[PriorSetRecord]:
    """Every prior set of the study's participants, oldest first."""
    return prior_sets.study_prior_sets(db, study_id)


@router.get("/api/prior-sets/{prior_set_id}", response_model=PriorSetOut)
def get_prior_set(prior_set_id: PriorSetId, user: CurrentUser, db: SessionDep
                  ) -> PriorSetRecord:
    """One prior set."""
    return prior_sets.one_prior_set(db, prior_set_id)
