"""Preferences given by participants, unblinded for the experimenter."""

from __future__ import annotations

from fastapi import APIRouter, Request

from backend.api.deps import CurrentUser, SessionDep
from backend.api.errors import AUTH_RESPONSES, INVALID, NOT_FOUND, one_or_404
from backend.api.params import ParticipantId
from backend.db.models import Participant
from backend.schemas.questionnaires import PreferenceOut
from backend.study import questionnaire_answers
from backend.study.access import may_unblind
from backend.study.blinding import labels_of

router = APIRouter(tags=["preferences"], responses={**AUTH_RESPONSES, **NOT_FOUND, **INVALID})


@router.get("/api/participants/{participant_id}/preferences",
            response_model=list[PreferenceOut])
def list_preferences(participant_id: ParticipantId, request: Request, user: CurrentUser,
                     db: SessionDep) -> list[PreferenceOut]:
    """The participant's preferences with the controller each label stands for (for
    the study's owners; null for other roles)."""
    one_or_404(db, Participant, participant_id, "participant")
    labels = labels_of(db, participant_id) if may_unblind(request.state) else {}
    rows = questionnaire_answers.preferences_of(db, participant_id)
    return [PreferenceOut(id=p.id, participant_id=p.participant_id, choice=p.choice,
                          controller=labels.get(p.choice), submitted_at=p.submitted_at)
            for p in rows]
