"""What the worker is doing for the study: at most one recording or trial at a time.

Starting one switches the worker's controller, which starts a new run; the recording or
trial keeps that run's id, so its ticks are exactly the run's ticks.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.api.errors import conflict
from backend.db.evidence import Recording, Trial


def ensure_idle(db: Session) -> None:
    """409 if a recording or a trial is already running."""
    rec = db.scalar(select(Recording.id).where(Recording.status == "recording"))
    if rec is not None:
        conflict("recording", f"recording {rec} is still running; stop it first")
    trial = db.scalar(select(Trial.id).where(Trial.status == "running"))
    if trial is not None:
        conflict("trial", f"trial {trial} is still running; stop it first")
