"""The lab's side of a session: event markers, the LSL marker streams of other software
the experimenter subscribed to, and LabRecorder XDF files attached to a session.

A marker keeps two times: `t`, the device time of the tick it belongs to (the axis of
every plot and export), and `lsl_time`, the same instant on the Lab Streaming Layer
clock (what other devices' data in an XDF file are stamped with).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    String,
    Text,
)
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import Base, utcnow


class StudyMarkerLabels(Base):
    """The marker buttons a study's console shows (one hotkey each, in order)."""

    __tablename__ = "study_marker_labels"

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True)
    labels: Mapped[list[str]] = mapped_column(JSON, default=list)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class MarkerStream(Base):
    """An LSL marker stream of other software whose markers a session stores."""

    __tablename__ = "lab_marker_streams"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    stream_type: Mapped[str] = mapped_column(String(100), default="")
    source_id: Mapped[str] = mapped_column(String(200), default="")
    hostname: Mapped[str] = mapped_column(String(200), default="")
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: Why the subscription was closed by the server (empty: it was not): a name the
    #: resolver cannot search for, or an inlet that failed. A failed subscription is
    #: inactive and is not resumed at start.
    error: Mapped[str] = mapped_column(Text, default="", server_default="")


class Marker(Base):
    """One event marker: from the console, from a subscribed LSL stream, or from the
    system (trial start and stop, calibration)."""

    __tablename__ = "markers"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    trial_id: Mapped[int | None] = mapped_column(
        ForeignKey("trials.id", ondelete="SET NULL"), index=True)
    run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id", ondelete="SET NULL"))
    t: Mapped[float | None] = mapped_column(Float)
    lsl_time: Mapped[float | None] = mapped_column(Float)
    label: Mapped[str] = mapped_column(String(100))
    note: Mapped[str] = mapped_column(Text, default="")
    source: Mapped[str] = mapped_column(String(16))
    stream_id: Mapped[int | None] = mapped_column(
        ForeignKey("lab_marker_streams.id", ondelete="SET NULL"))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))


class XdfAttachment(Base):
    """A LabRecorder XDF file attached to a session, kept whole, with the summary of its
    streams and which of the session's trials each covers."""

    __tablename__ = "xdf_attachments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    filename: Mapped[str] = mapped_column(String(255))
    size_bytes: Mapped[int] = mapped_column(Integer)
    sha256: Mapped[str] = mapped_column(String(64))
    content: Mapped[bytes] = mapped_column(LargeBinary)
    streams: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
