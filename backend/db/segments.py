"""The columns a lift segment has wherever it is marked (`lift_segments` in a recording,
`trial_segments` in a trial): one definition for both tables. Sample indices count from
the first tick of the recording or trial the segment belongs to."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import DateTime, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import utcnow


class SegmentColumns:
    """Mixin: start, peak and end sample of one lift, its label, who set it and when.
    The table adds its primary key and the row it belongs to; the columns here come
    after those (`sort_order`), as the migrations and the exports have them."""

    start: Mapped[int] = mapped_column(Integer, sort_order=10)
    peak: Mapped[int] = mapped_column(Integer, sort_order=10)
    end: Mapped[int] = mapped_column(Integer, sort_order=10)
    label: Mapped[str] = mapped_column(String(32), default="unlabelled", sort_order=10)
    source: Mapped[str] = mapped_column(String(16), default="auto", sort_order=10)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow,
                                                 sort_order=10)
