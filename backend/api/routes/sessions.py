"""Sessions: a participant's visits (data collection or evaluation)."""

from __future__ import annotations

from fastapi import APIRouter

from backend.api.deps import CurrentUser, SessionDep
from backend.api.errors import AUTH_RESPONSES, BODY, NOT_FOUND, one_or_404
from backend.api.params import ParticipantId, SessionId
from backend.db.models import Participant, StudySession
from backend.schemas.sessions import SessionIn, SessionOut, SessionUpdate
from backend.study import visits

router = APIRouter(tags=["sessions"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})


@router.get("/api/participants/{participant_id}/sessions", response_model=list[SessionOut])
def list_sessions(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
                  ) -> list[StudySession]:
    """A participant's sessions in the order they happened."""
    one_or_404(db, Participant, participant_id, "participant")
    return visits.of_participant(db, participant_id)


@router.post("/api/participants/{participant_id}/sessions", response_model=SessionOut,
             status_code=201)
def create_session(participant_id: ParticipantId, body: SessionIn, user: CurrentUser,
                   db: SessionDep) -> StudySession:
    """Start a session record with the exoskeleton's settings."""
    one_or_404(db, Participant, participant_id, "participant")
    return visits.start(db, user, participant_id, body)


@router.get("/api/sessions/{session_id}", response_model=SessionOut)
def get_session(session_id: SessionId, user: CurrentUser, db: SessionDep) -> StudySession:
    """One session."""
    return one_or_404(db, StudySession, session_id, "session")


@router.patch("/api/sessions/{session_id}", response_model=SessionOut)
def update_session(session_id: SessionId, body: SessionUpdate, user: CurrentUser,
                   db: SessionDep) -> StudySession:
    """Correct the precompression or the notes."""
    s = one_or_404(db, StudySession, session_id, "session")
    return visits.correct(db, user, s, body)
