"""Reading a trial's event markers back, for the figures and the API.

Storing them (which trial a marker belongs to, the study's labels) is the lab's
(`backend.lab.markers`); reading them is analysis, which the lab's exports and the
results both build on.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.lab import Marker


def trial_markers(db: Session, trial_id: int) -> list[Marker]:
    """A trial's markers in time order."""
    return list(db.scalars(select(Marker).where(Marker.trial_id == trial_id)
                           .order_by(Marker.t, Marker.id)))
