"""Study records: experimenters and logins, studies, participants and their blinding key,
sessions, questionnaire instruments, participant links, responses, preferences, audit log.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def _tz() -> sa.DateTime:
    return sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "users",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("username", sa.String(length=64), nullable=False, unique=True),
        sa.Column("password_hash", sa.String(length=255), nullable=False),
        sa.Column("active", sa.Boolean(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
    )
    op.create_table(
        "auth_tokens",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("user_id", sa.Integer(), sa.ForeignKey("users.id", ondelete="CASCADE"),
                  nullable=False),
        sa.Column("token_hash", sa.String(length=64), nullable=False, unique=True),
        sa.Column("kind", sa.String(length=16), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.Column("expires_at", _tz(), nullable=False),
        sa.Column("revoked_at", _tz(), nullable=True),
    )
    op.create_index("ix_auth_tokens_user_id", "auth_tokens", ["user_id"])
    op.create_table(
        "studies",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("name", sa.String(length=200), nullable=False, unique=True),
        sa.Column("description", sa.Text(), nullable=False),
        sa.Column("created_by", sa.Integer(), sa.ForeignKey("users.id", ondelete="SET NULL"),
                  nullable=True),
        sa.Column("created_at", _tz(), nullable=False),
    )
    op.create_table(
        "participants",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("study_id", sa.Integer(), sa.ForeignKey("studies.id", ondelete="CASCADE"),
                  nullable=False),
        sa.Column("code", sa.String(length=32), nullable=False),
        sa.Column("age", sa.Integer(), nullable=True),
        sa.Column("sex", sa.String(length=16), nullable=True),
        sa.Column("height_m", sa.Float(), nullable=True),
        sa.Column("mass_kg", sa.Float(), nullable=True),
        sa.Column("consent_date", sa.Date(), nullable=True),
        sa.Column("notes", sa.Text(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.UniqueConstraint("study_id", "code", name="uq_participants_study_code"),
    )
    op.create_index("ix_participants_study_id", "participants", ["study_id"])
    op.create_table(
        "condition_labels",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("participant_id", sa.Integer(),
                  sa.ForeignKey("participants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("label", sa.String(length=16), nullable=False),
        sa.Column("controller", sa.String(length=32), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.UniqueConstraint("participant_id", "label", name="uq_condition_labels_label"),
        sa.UniqueConstraint("participant_id", "controller",
                            name="uq_condition_labels_controller"),
    )
    op.create_index("ix_condition_labels_participant_id", "condition_labels",
                    ["participant_id"])
    op.create_table(
        "study_sessions",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("participant_id", sa.Integer(),
                  sa.ForeignKey("participants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("kind", sa.String(length=32), nullable=False),
        sa.Column("precompression_pct", sa.Float(), nullable=False),
        sa.Column("started_at", _tz(), nullable=False),
        sa.Column("notes", sa.Text(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
    )
    op.create_index("ix_study_sessions_participant_id", "study_sessions", ["participant_id"])
    op.create_table(
        "questionnaire_instruments",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("key", sa.String(length=64), nullable=False),
        sa.Column("version", sa.String(length=32), nullable=False),
        sa.Column("title", sa.String(length=200), nullable=False),
        sa.Column("definition", sa.JSON(), nullable=False),
        sa.Column("built_in", sa.Boolean(), nullable=False),
        sa.Column("created_by", sa.Integer(), sa.ForeignKey("users.id", ondelete="SET NULL"),
                  nullable=True),
        sa.Column("created_at", _tz(), nullable=False),
        sa.UniqueConstraint("key", "version", name="uq_instruments_key_version"),
    )
    op.create_table(
        "participant_links",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("participant_id", sa.Integer(),
                  sa.ForeignKey("participants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("token_hash", sa.String(length=64), nullable=False, unique=True),
        sa.Column("forms_due", sa.JSON(), nullable=False),
        sa.Column("preference_due", sa.Boolean(), nullable=False),
        sa.Column("created_by", sa.Integer(), sa.ForeignKey("users.id", ondelete="SET NULL"),
                  nullable=True),
        sa.Column("created_at", _tz(), nullable=False),
        sa.Column("expires_at", _tz(), nullable=False),
        sa.Column("used_at", _tz(), nullable=True),
    )
    op.create_index("ix_participant_links_participant_id", "participant_links",
                    ["participant_id"])
    op.create_table(
        "questionnaire_responses",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("participant_id", sa.Integer(),
                  sa.ForeignKey("participants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("link_id", sa.Integer(),
                  sa.ForeignKey("participant_links.id", ondelete="SET NULL"), nullable=True),
        sa.Column("instrument_id", sa.Integer(),
                  sa.ForeignKey("questionnaire_instruments.id"), nullable=False),
        sa.Column("instrument_key", sa.String(length=64), nullable=False),
        sa.Column("instrument_version", sa.String(length=32), nullable=False),
        sa.Column("condition_label", sa.String(length=16), nullable=True),
        sa.Column("answers", sa.JSON(), nullable=False),
        sa.Column("score", sa.Float(), nullable=False),
        sa.Column("subscale_scores", sa.JSON(), nullable=False),
        sa.Column("submitted_at", _tz(), nullable=False),
    )
    op.create_index("ix_questionnaire_responses_participant_id", "questionnaire_responses",
                    ["participant_id"])
    op.create_table(
        "preferences",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("participant_id", sa.Integer(),
                  sa.ForeignKey("participants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("link_id", sa.Integer(),
                  sa.ForeignKey("participant_links.id", ondelete="SET NULL"), nullable=True),
        sa.Column("choice", sa.String(length=16), nullable=False),
        sa.Column("submitted_at", _tz(), nullable=False),
    )
    op.create_index("ix_preferences_participant_id", "preferences", ["participant_id"])
    op.create_table(
        "audit_log",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("at", _tz(), nullable=False),
        sa.Column("user_id", sa.Integer(), sa.ForeignKey("users.id", ondelete="SET NULL"),
                  nullable=True),
        sa.Column("actor", sa.String(length=100), nullable=False),
        sa.Column("action", sa.String(length=32), nullable=False),
        sa.Column("entity", sa.String(length=64), nullable=False),
        sa.Column("entity_id", sa.String(length=64), nullable=True),
        sa.Column("details", sa.JSON(), nullable=False),
    )
    op.create_index("ix_audit_log_at", "audit_log", ["at"])


def downgrade() -> None:
    op.drop_index("ix_audit_log_at", table_name="audit_log")
    op.drop_table("audit_log")
    op.drop_index("ix_preferences_participant_id", table_name="preferences")
    op.drop_table("preferences")
    op.drop_index("ix_questionnaire_responses_participant_id",
                  table_name="questionnaire_responses")
    op.drop_table("questionnaire_responses")
    op.drop_index("ix_participant_links_participant_id", table_name="participant_links")
    op.drop_table("participant_links")
    op.drop_table("questionnaire_instruments")
    op.drop_index("ix_study_sessions_participant_id", table_name="study_sessions")
    op.drop_table("study_sessions")
    op.drop_index("ix_condition_labels_participant_id", table_name="condition_labels")
    op.drop_table("condition_labels")
    op.drop_index("ix_participants_study_id", table_name="participants")
    op.drop_table("participants")
    op.drop_table("studies")
    op.drop_index("ix_auth_tokens_user_id", table_name="auth_tokens")
    op.drop_table("auth_tokens")
    op.drop_table("users")
