"""The study's chain of evidence around the control loop: recordings and their lift
segments, model sets and utility sets with their provenance, controller configurations,
evaluation trials with the exact configuration they ran, lock events, background jobs.

A recording and a trial each own one worker `Run`: their ticks are that run's ticks.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    UniqueConstraint,
    text,
)
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import Base, utcnow
from backend.db.segments import SegmentColumns


class Recording(Base):
    """A continuous 100 Hz stream recorded in data-collection mode (no locks)."""

    __tablename__ = "recordings"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id", ondelete="SET NULL"))
    label: Mapped[str] = mapped_column(String(200), default="")
    status: Mapped[str] = mapped_column(String(16), default="recording")
    started_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    ended_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    first_tick_id: Mapped[int | None] = mapped_column(Integer)
    last_tick_id: Mapped[int | None] = mapped_column(Integer)
    notes: Mapped[str] = mapped_column(Text, default="")
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))

    # At most one recording runs: the database refuses a second, whatever the server's
    # own lock does (a partial unique index: SQLite and PostgreSQL both have them).
    __table_args__ = (
        Index("uq_recordings_one_running", "status", unique=True,
              sqlite_where=text("status = 'recording'"),
              postgresql_where=text("status = 'recording'")),
    )


class LiftSegment(SegmentColumns, Base):
    """One lift in a recording: sample indices from its first tick, and a label."""

    __tablename__ = "lift_segments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    recording_id: Mapped[int] = mapped_column(
        ForeignKey("recordings.id", ondelete="CASCADE"), index=True)


class TrialSegment(SegmentColumns, Base):
    """One lift in a trial, marked by the experimenter: the ground truth of a trial on
    hardware, where no simulation labels the ticks. Sample indices from the trial's
    first tick."""

    __tablename__ = "trial_segments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    trial_id: Mapped[int] = mapped_column(
        ForeignKey("trials.id", ondelete="CASCADE"), index=True)


class ModelSetRecord(Base):
    """A motion model set fitted from chosen segments; the JSON keeps its provenance."""

    __tablename__ = "model_sets"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    name: Mapped[str] = mapped_column(String(200))
    status: Mapped[str] = mapped_column(String(16), default="pending")
    params: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    segment_ids: Mapped[list[int]] = mapped_column(JSON, default=list)
    document: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    error: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    #: population (from a study's demonstrations) or personal (one participant's).
    kind: Mapped[str] = mapped_column(String(16), default="population",
                                      server_default="population")
    #: ppca (fitted from the segments alone) or map (the population set `base_model_set_id`
    #: adapted to the participant's demonstrations).
    method: Mapped[str] = mapped_column(String(32), default="ppca", server_default="ppca")
    #: The wearer of a personal set (withdrawal takes it with them).
    participant_id: Mapped[int | None] = mapped_column(ForeignKey(
        "participants.id", ondelete="CASCADE", name="fk_model_sets_participant_id"),
        index=True)
    #: The population set a personal set was adapted from (or compared with).
    base_model_set_id: Mapped[int | None] = mapped_column(ForeignKey(
        "model_sets.id", ondelete="SET NULL", name="fk_model_sets_base_model_set_id"))


class UtilitySetRecord(Base):
    """A utility table for one actuator setting and human dataset."""

    __tablename__ = "utility_sets"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    name: Mapped[str] = mapped_column(String(200))
    precompression_pct: Mapped[float] = mapped_column(Float)
    human_source: Mapped[str] = mapped_column(String(200))
    status: Mapped[str] = mapped_column(String(16), default="pending")
    human_data: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    document: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    error: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))


class Job(Base):
    """A background computation (model fitting, utilities, a virtual cohort) with its
    progress. `status`: queued, running, then done (succeeded), failed or cancelled;
    `message` is the result's summary or the reason it failed or was cancelled."""

    __tablename__ = "jobs"
    # One job per slot: the database refuses a second unfinished job of an account in
    # the same slot, whatever the timing of the requests (NULLs never collide).
    __table_args__ = (UniqueConstraint("created_by", "kind", "quota_slot",
                                       name="uq_jobs_quota_slot"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    kind: Mapped[str] = mapped_column(String(32))
    target_id: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(16), default="queued", index=True)
    #: Which runner thread takes it: `study` (short study jobs) or `cohort` (long).
    lane: Mapped[str] = mapped_column(String(16), default="study",
                                      server_default="study")
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    message: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    created_by: Mapped[int | None] = mapped_column(
        ForeignKey("users.id", ondelete="SET NULL", name="fk_jobs_created_by"))
    #: While unfinished, a job limited per account holds one of its account's slots
    #: 0..limit-1 for its kind; a finished job frees it (null).
    quota_slot: Mapped[int | None] = mapped_column(Integer, nullable=True)


class Trial(Base):
    """One evaluation trial: a controller on a task, in its planned order."""

    __tablename__ = "trials"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("study_sessions.id", ondelete="CASCADE"), index=True)
    controller: Mapped[str] = mapped_column(String(32))
    task: Mapped[str] = mapped_column(String(32))
    planned_order: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(16), default="planned")
    model_set_id: Mapped[int | None] = mapped_column(
        ForeignKey("model_sets.id", ondelete="SET NULL"))
    utility_set_id: Mapped[int | None] = mapped_column(
        ForeignKey("utility_sets.id", ondelete="SET NULL"))
    run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id", ondelete="SET NULL"))
    config_snapshot: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    ended_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    end_reason: Mapped[str] = mapped_column(Text, default="")
    #: Ticks stored for the trial when it ended (its run's), also when interrupted.
    tick_count: Mapped[int | None] = mapped_column(Integer)
    #: What is wrong with the trial's data, e.g. device time gaps or going backwards:
    #: `backend.live.trial_quality.QualityFlags` as JSON; empty when nothing is.
    quality_flags: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    #: The hardware profile in effect when the trial started (backend/db/hardware.py).
    hardware_profile_id: Mapped[int | None] = mapped_column(ForeignKey(
        "hardware_profiles.id", ondelete="SET NULL", name="fk_trials_hardware_profile_id"))
    #: The blinding key of the trial's condition (`backend.study.conditions`), e.g.
    #: "umc+personal"; "" means the controller's own name (population models, equal
    #: priors: every trial planned before conditions existed).
    condition: Mapped[str] = mapped_column(String(64), default="", server_default="")
    #: Which models the condition runs: population or personal (the participant's
    #: personal set, fixed at plan time or resolved when the trial starts).
    models: Mapped[str] = mapped_column(String(16), default="population",
                                        server_default="population")
    #: The participant's prior set the condition runs with (None: equal priors).
    prior_set_id: Mapped[int | None] = mapped_column(ForeignKey(
        "prior_sets.id", ondelete="SET NULL", name="fk_trials_prior_set_id"))
    #: A demonstration block: how many demonstrations of each motion it asks for.
    demonstrations: Mapped[dict[str, Any] | None] = mapped_column(JSON)

    # At most one trial runs: the database refuses a second (see Recording).
    __table_args__ = (
        Index("uq_trials_one_running", "status", unique=True,
              sqlite_where=text("status = 'running'"),
              postgresql_where=text("status = 'running'")),
    )


class LockEvent(Base):
    """A change of the held lock command or of the mechanism, per side, in a trial."""

    __tablename__ = "lock_events"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id", ondelete="CASCADE"),
                                          index=True)
    t: Mapped[float] = mapped_column(Float)
    side: Mapped[str] = mapped_column(String(8))
    kind: Mapped[str] = mapped_column(String(32))
    torque_peak: Mapped[float | None] = mapped_column(Float)
