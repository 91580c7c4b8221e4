"""Muscle activity's tables: a study's montage versions and EMG analysis settings, the
EMG streams a session subscribed to, the recordings (one row per file in the EMG folder,
`backend.emg.store`), and a session's MVC steps.

Times: a recording's timestamps plus `time_offset_s` are on the session clock, the LSL
clock of this server on which markers keep `lsl_time` (live streams are on it already,
offset 0; a file import finds the offset from the session's markers).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import Base, utcnow


class EmgMontage(Base):
    """One version of a study's montage (`controller.emg.montage.Montage.to_dict`).
    A change adds a version; recordings keep the version their channels were mapped by."""

    __tablename__ = "emg_montages"
    __table_args__ = (UniqueConstraint("study_id", "version", name="uq_emg_montages_version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    version: Mapped[int] = mapped_column(Integer)
    placement_scheme: Mapped[str] = mapped_column(Text, default="")
    channels: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))


class EmgAnalysisSettings(Base):
    """A study's EMG processing chain and normalisation method
    (`controller.emg.processing.EmgProcessing.to_dict`), saved with every result."""

    __tablename__ = "emg_analysis_settings"

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True)
    processing: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    mains_hz: Mapped[int] = mapped_column(Integer, default=50)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class EmgStream(Base):
    """An LSL stream of type EMG a session records (as `MarkerStream` for markers)."""

    __tablename__ = "emg_streams"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    source_id: Mapped[str] = mapped_column(String(200), default="")
    montage_id: Mapped[int] = mapped_column(ForeignKey("emg_montages.id", ondelete="RESTRICT"))
    #: Stream labels left out on purpose (spare inputs), as the subscriber said.
    ignored_labels: Mapped[list[str]] = mapped_column(JSON, default=list)
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    error: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


#: The statuses of a recording whose file an analysis reads: complete, or interrupted (a
#: live recording a killed server left, finalised at the next start with every whole
#: chunk it holds and the flag `interrupted`: the trials before the crash are in it).
ANALYSED_STATUSES = ("complete", "interrupted")


class EmgRecording(Base):
    """One EMG recording file: where it came from, its span, and what is wrong with it."""

    __tablename__ = "emg_recordings"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    montage_id: Mapped[int] = mapped_column(ForeignKey("emg_montages.id", ondelete="RESTRICT"))
    montage_version: Mapped[int] = mapped_column(Integer)
    #: "lsl", "xdf", "edf", "bdf" or "simulated".
    source: Mapped[str] = mapped_column(String(16))
    stream_id: Mapped[int | None] = mapped_column(
        ForeignKey("emg_streams.id", ondelete="SET NULL"))
    #: "recording" while a live stream writes it, then "complete"; "interrupted" when a
    #: killed server left it recording (`backend.emg.recovery`).
    status: Mapped[str] = mapped_column(String(16), default="complete")
    filename: Mapped[str] = mapped_column(String(255), default="")
    fs: Mapped[float] = mapped_column(Float)
    channel_count: Mapped[int] = mapped_column(Integer)
    #: The file's channel labels in order (the montage's labels; the montage maps them).
    labels: Mapped[list[str]] = mapped_column(JSON, default=list)
    n_samples: Mapped[int] = mapped_column(BigInteger, default=0)
    #: Session clock = file timestamp + this.
    time_offset_s: Mapped[float] = mapped_column(Float, default=0.0)
    #: How the offset was found (LSL clock correction, an annotation matched to a
    #: marker, a stated offset after a trial's start).
    alignment: Mapped[str] = mapped_column(Text, default="")
    t_start: Mapped[float | None] = mapped_column(Float)
    t_end: Mapped[float | None] = mapped_column(Float)
    #: The session's trials the recording covers: [{trial_id, start, stop, complete}],
    #: times on the session clock.
    trials: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    size_bytes: Mapped[int] = mapped_column(BigInteger, default=0)
    sha256: Mapped[str] = mapped_column(String(64), default="")
    #: `backend.emg.quality_summary.QualitySummary.to_dict`: flags and where.
    quality: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))


class MvcStep(Base):
    """A maximum-voluntary-contraction step of a session's plan: one muscle (both
    sides, or one), so many repetitions, each timed by an `mvc_start` and an `mvc_stop`
    marker (`repetitions_done`: [{rep, side, start_marker_id, stop_marker_id}])."""

    __tablename__ = "mvc_steps"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    planned_order: Mapped[int] = mapped_column(Integer)
    muscle: Mapped[str] = mapped_column(String(40))
    #: "left", "right" or "both".
    side: Mapped[str] = mapped_column(String(8), default="both")
    repetitions: Mapped[int] = mapped_column(Integer)
    rest_s: Mapped[float] = mapped_column(Float, default=60.0)
    contraction_s: Mapped[float] = mapped_column(Float, default=5.0)
    repetitions_done: Mapped[list[dict[str, Any]]] = mapped_column(JSON, default=list)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
