"""Per-wearer prior sets (issue 30): priors learned from a participant's use, versioned
per participant, always inside the safety bound of the utility set they were made for.

Personal model sets are rows of `model_sets` (`kind="personal"`, with the participant
and the population set they adapt); this module holds what has no table of its own.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, DateTime, ForeignKey, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import Base, utcnow


class PriorSetRecord(Base):
    """One version of a participant's priors: the `LearnedPriors` document (values the
    controller uses, the unbounded estimate, counts, sources) and the utility set whose
    safety bound the values were checked against."""

    __tablename__ = "prior_sets"
    __table_args__ = (UniqueConstraint("participant_id", "version",
                                       name="uq_prior_sets_participant_version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    #: 1, 2, ... per participant, in the order made.
    version: Mapped[int] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(200))
    #: dirichlet (confirmed motions), label-shift-em (unconfirmed use), equal or import.
    method: Mapped[str] = mapped_column(String(32))
    status: Mapped[str] = mapped_column(String(16), default="ready")
    utility_set_id: Mapped[int | None] = mapped_column(
        ForeignKey("utility_sets.id", ondelete="SET NULL"))
    previous_id: Mapped[int | None] = mapped_column(
        ForeignKey("prior_sets.id", ondelete="SET NULL"))
    params: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    document: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    error: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
