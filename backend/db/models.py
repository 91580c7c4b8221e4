"""ORM models. The tick table's columns come from `controller.tick_record.TickRecord`, the one
definition of a tick, so the stored row and the worker's record cannot drift apart
(a test checks the migrations build the same schema)."""

from __future__ import annotations

import dataclasses
import secrets
from datetime import UTC, date, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    Column,
    Date,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Table,
    Text,
    UniqueConstraint,
    false,
)
from sqlalchemy import text as sql_text
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeEngine

from controller.tick_record import TickRecord


def utcnow() -> datetime:
    """Timezone-aware now; stored as UTC."""
    return datetime.now(UTC)


#: Largest date shift of the de-identified export, in days (under a year, so seasons
#: and weekdays may move but intervals within a participant stay true).
MAX_SHIFT_DAYS = 364


def draw_date_shift() -> int:
    """A date shift in days, 1..MAX_SHIFT_DAYS, from the system's secure random source
    (a predictable shift would undo the de-identification)."""
    return secrets.randbelow(MAX_SHIFT_DAYS) + 1


class Base(DeclarativeBase):
    """Declarative base of every table."""


class Run(Base):
    """One continuous stream of ticks: one worker lifetime with one controller setting.

    A restart of the worker, or a change of controller, starts a new run, so every tick
    can be traced to the exact configuration that produced it.
    """

    __tablename__ = "runs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    started_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    ended_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    device_kind: Mapped[str] = mapped_column(String(32))
    controller: Mapped[str] = mapped_column(String(32))
    config_json: Mapped[str] = mapped_column(Text, default="{}")
    worker_pid: Mapped[int | None] = mapped_column(Integer)
    end_reason: Mapped[str | None] = mapped_column(String(200))
    tick_count: Mapped[int] = mapped_column(BigInteger, default=0)


def _sql_type(tp: object) -> TypeEngine[Any]:
    mapping: dict[object, TypeEngine[Any]] = {
        "int": BigInteger(),
        "float": Float(),
        "bool": Boolean(),
        "str": String(32),
    }
    return mapping[tp]


def tick_columns() -> list[Column[Any]]:
    """The tick table's data columns, in `TickRecord` order."""
    cols: list[Column[Any]] = []
    for f in dataclasses.fields(TickRecord):
        cols.append(Column(f.name, _sql_type(f.type), nullable=True))
    return cols


ticks_table = Table(
    "ticks",
    Base.metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
    *tick_columns(),
    Index("ix_ticks_run_t", "run_id", "t"),
)

TICK_DATA_COLUMNS: tuple[str, ...] = TickRecord.field_names()


# --- Study records -------------------------------------------------------------------
# Everything a study keeps besides ticks. JSON columns use SQLAlchemy's portable JSON
# type (TEXT on SQLite, json on PostgreSQL), so nothing here is SQLite-only.


class User(Base):
    """An experimenter account. Only the argon2 hash of the password is kept."""

    __tablename__ = "users"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    username: Mapped[str] = mapped_column(String(64), unique=True)
    password_hash: Mapped[str] = mapped_column(String(255))
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: Global role: "admin" manages accounts and acts as owner of every study; "member"
    #: has only the roles its study memberships give (backend/study/access.py).
    role: Mapped[str] = mapped_column(String(16), default="member", server_default="member")
    #: True while the password is one printed in the README (the demo account's): the
    #: server refuses a non-loopback host and every page warns until it is changed.
    password_published: Mapped[bool] = mapped_column(Boolean, default=False,
                                                     server_default=false())


class AuthToken(Base):
    """A login: a browser session (cookie) or a bearer token for scripts.

    Only a SHA-256 of the token is stored, so a copy of the database cannot be used to
    log in; revoking is setting `revoked_at` (logout), which keeps the history.
    """

    __tablename__ = "auth_tokens"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"),
                                         index=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    kind: Mapped[str] = mapped_column(String(16))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))


class Study(Base):
    """A study: the container of participants, their sessions and their answers."""

    __tablename__ = "studies"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    description: Mapped[str] = mapped_column(Text, default="")
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: What withdrawal does to a participant's data: "erase" (delete everything) or
    #: "exclude" (keep, marked withdrawn and left out of results and exports), as the
    #: study's approved protocol says.
    withdrawal_policy: Mapped[str] = mapped_column(String(16), default="erase",
                                                   server_default="erase")
    #: Days every date of the study's own rows (model and utility sets) moves back in
    #: the de-identified export; drawn once, so every download shifts the same way.
    date_shift_days: Mapped[int] = mapped_column(Integer, default=draw_date_shift)
    #: The dataset description of its exports (authors, licence, institution, ...;
    #: `backend.schemas.studies.DatasetInfo`).
    dataset_info: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)


class StudyMember(Base):
    """An account's role in a study (owner, experimenter, viewer), optionally limited
    to one site's participants (REDCap's data access groups)."""

    __tablename__ = "study_members"
    __table_args__ = (UniqueConstraint("study_id", "user_id", name="uq_study_members"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"),
                                         index=True)
    role: Mapped[str] = mapped_column(String(16))
    site: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ConsentDocument(Base):
    """One version of a study's consent text; participants record the version they
    consented to. Versions are added, never edited."""

    __tablename__ = "consent_documents"
    __table_args__ = (UniqueConstraint("study_id", "version", name="uq_consent_version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    version: Mapped[str] = mapped_column(String(32))
    text: Mapped[str] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class LoginFailure(Base):
    """A failed login, kept for throttling (per account and per address) and audit."""

    __tablename__ = "login_failures"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow, index=True)
    username: Mapped[str] = mapped_column(String(64), index=True)
    address: Mapped[str] = mapped_column(String(64), index=True)


class LoginThrottle(Base):
    """The login attempts one account (`account:NAME`) or one address (`address:IP`)
    has made in its current window. An attempt is counted before its password is
    checked, by one conditional UPDATE (backend/study/accounts.py), so concurrent
    attempts cannot all pass the limit; a successful login gives its attempt back."""

    __tablename__ = "login_throttles"

    key: Mapped[str] = mapped_column(String(80), primary_key=True)
    window_start: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    attempts: Mapped[int] = mapped_column(Integer, default=0)


class Participant(Base):
    """A participant under a pseudonymous code; no name or contact is ever stored."""

    __tablename__ = "participants"
    __table_args__ = (UniqueConstraint("study_id", "code", name="uq_participants_study_code"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"),
                                          index=True)
    code: Mapped[str] = mapped_column(String(32))
    age: Mapped[int | None] = mapped_column(Integer)
    sex: Mapped[str | None] = mapped_column(String(16))
    height_m: Mapped[float | None] = mapped_column(Float)
    mass_kg: Mapped[float | None] = mapped_column(Float)
    consent_date: Mapped[date | None] = mapped_column(Date)
    notes: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: The site that recruited the participant (None: the study has one site).
    site: Mapped[str | None] = mapped_column(String(64))
    #: The consent document version the participant agreed to (see ConsentDocument).
    consent_version: Mapped[str | None] = mapped_column(String(32))
    #: Set when a participant of an "exclude" study withdraws; erased ones are deleted.
    withdrawn_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    #: Days this participant's dates move back in the de-identified export: drawn once
    #: (1..MAX_SHIFT_DAYS) and kept, so that two downloads cannot be compared to narrow
    #: the true dates down.
    date_shift_days: Mapped[int] = mapped_column(Integer, default=draw_date_shift)


class ConditionLabel(Base):
    """The blinding key: which real controller hides behind label "A" for a participant.

    Participants only ever see the label; responses and preferences store the label, and
    this table unblinds them for the experimenter.
    """

    __tablename__ = "condition_labels"
    __table_args__ = (
        UniqueConstraint("participant_id", "label", name="uq_condition_labels_label"),
        UniqueConstraint("participant_id", "controller", name="uq_condition_labels_controller"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    label: Mapped[str] = mapped_column(String(16))
    controller: Mapped[str] = mapped_column(String(32))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class StudySession(Base):
    """One visit of a participant: data collection (demonstrations) or evaluation."""

    __tablename__ = "study_sessions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(32))
    precompression_pct: Mapped[float] = mapped_column(Float)
    started_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    notes: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: The hardware profile in effect when the session was created (backend/db/hardware.py).
    hardware_profile_id: Mapped[int | None] = mapped_column(ForeignKey(
        "hardware_profiles.id", ondelete="SET NULL",
        name="fk_study_sessions_hardware_profile_id"))


class QuestionnaireInstrument(Base):
    """A questionnaire definition (items, scale, scoring), stored whole as JSON.

    Built-in instruments (`built_in`, no study) ship with ExoStudy, are shared by every
    study and never change. Every other instrument belongs to the study that imported
    it (`study_id`) and is offered to that study's participants only, so one study's
    experimenter cannot change what another study's participants are shown. A custom
    instrument whose study could not be told when 0011 migrated it keeps `study_id`
    NULL: it stays stored (its responses point at it) but no link can use it.
    Key and version identify an instrument within its study (or among the built-ins); a
    response points at the exact row it was scored with, so changing an instrument
    means adding a version, never editing one.
    """

    __tablename__ = "questionnaire_instruments"
    __table_args__ = (
        UniqueConstraint("study_id", "key", "version", name="uq_instruments_study_key_version"),
        # Built-ins have no study, and NULLs never collide in a unique constraint.
        Index("uq_instruments_builtin_key_version", "key", "version", unique=True,
              sqlite_where=sql_text("built_in"), postgresql_where=sql_text("built_in")),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int | None] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    key: Mapped[str] = mapped_column(String(64))
    version: Mapped[str] = mapped_column(String(32))
    title: Mapped[str] = mapped_column(String(200))
    definition: Mapped[dict[str, Any]] = mapped_column(JSON)
    built_in: Mapped[bool] = mapped_column(Boolean, default=False)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ParticipantLink(Base):
    """An unguessable link for one participant and the forms due.

    Only a SHA-256 of the token is stored. `forms_due` is a list of
    `{"instrument_id", "instrument_key", "instrument_version", "condition_label"}`: the
    id pins the exact instrument row the link was made with; each form can be
    submitted once, and the link closes (`used_at`) when everything due is in.
    """

    __tablename__ = "participant_links"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    forms_due: Mapped[list[dict[str, Any]]] = mapped_column(JSON)
    preference_due: Mapped[bool] = mapped_column(Boolean, default=False)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    used_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))


class QuestionnaireResponse(Base):
    """A participant's answers to one instrument for one blinded condition, with the
    score computed at submission by that instrument version."""

    __tablename__ = "questionnaire_responses"
    # One response per form of a link, enforced by the database: parallel submissions
    # of the same form cannot both be stored (the loser gets 409).
    __table_args__ = (UniqueConstraint("link_id", "link_form", name="uq_responses_link_form"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    link_id: Mapped[int | None] = mapped_column(
        ForeignKey("participant_links.id", ondelete="SET NULL"))
    instrument_id: Mapped[int] = mapped_column(ForeignKey("questionnaire_instruments.id"))
    instrument_key: Mapped[str] = mapped_column(String(64))
    instrument_version: Mapped[str] = mapped_column(String(32))
    condition_label: Mapped[str | None] = mapped_column(String(16))
    answers: Mapped[dict[str, Any]] = mapped_column(JSON)
    #: Index of the form in its link's `forms_due` (None: not entered through a link).
    link_form: Mapped[int | None] = mapped_column(Integer)
    score: Mapped[float] = mapped_column(Float)
    subscale_scores: Mapped[dict[str, Any]] = mapped_column(JSON)
    submitted_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Preference(Base):
    """Which blinded condition the participant preferred ("none": no preference)."""

    __tablename__ = "preferences"
    # One preference per link, enforced by the database (parallel submissions: 409).
    __table_args__ = (UniqueConstraint("link_id", name="uq_preferences_link"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    link_id: Mapped[int | None] = mapped_column(
        ForeignKey("participant_links.id", ondelete="SET NULL"))
    choice: Mapped[str] = mapped_column(String(16))
    submitted_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class AuditEntry(Base):
    """Who created or changed what, and when. Written in the same transaction as the
    change, so an entry exists exactly when the change does."""

    __tablename__ = "audit_log"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow, index=True)
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    actor: Mapped[str] = mapped_column(String(100))
    action: Mapped[str] = mapped_column(String(32))
    entity: Mapped[str] = mapped_column(String(64))
    entity_id: Mapped[str | None] = mapped_column(String(64))
    details: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
