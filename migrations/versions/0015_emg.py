"""Muscle activity (issue 29): montage versions and EMG analysis settings per study, EMG
stream subscriptions, recordings (rows for the files in the EMG folder) and MVC steps.

Revision ID: 0015
Revises: 0014
Create Date: 2026-12-03 10:00:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0015"
down_revision = "0014"
branch_labels = None
depends_on = None


def _tz() -> sa.DateTime:
    return sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "emg_montages",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("placement_scheme", sa.Text(), nullable=False),
        sa.Column("channels", sa.JSON(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(["study_id"], ["studies.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("study_id", "version", name="uq_emg_montages_version"),
    )
    op.create_index("ix_emg_montages_study_id", "emg_montages", ["study_id"])
    op.create_table(
        "emg_analysis_settings",
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("processing", sa.JSON(), nullable=False),
        sa.Column("mains_hz", sa.Integer(), nullable=False),
        sa.Column("updated_at", _tz(), nullable=False),
        sa.ForeignKeyConstraint(["study_id"], ["studies.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("study_id"),
    )
    op.create_table(
        "emg_streams",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("session_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("source_id", sa.String(length=200), nullable=False),
        sa.Column("montage_id", sa.Integer(), nullable=False),
        sa.Column("ignored_labels", sa.JSON(), nullable=False),
        sa.Column("active", sa.Boolean(), nullable=False),
        sa.Column("error", sa.Text(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.ForeignKeyConstraint(["session_id"], ["study_sessions.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["montage_id"], ["emg_montages.id"], ondelete="RESTRICT"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_emg_streams_session_id", "emg_streams", ["session_id"])
    op.create_table(
        "emg_recordings",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("session_id", sa.Integer(), nullable=False),
        sa.Column("montage_id", sa.Integer(), nullable=False),
        sa.Column("montage_version", sa.Integer(), nullable=False),
        sa.Column("source", sa.String(length=16), nullable=False),
        sa.Column("stream_id", sa.Integer(), nullable=True),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("filename", sa.String(length=255), nullable=False),
        sa.Column("fs", sa.Float(), nullable=False),
        sa.Column("channel_count", sa.Integer(), nullable=False),
        sa.Column("labels", sa.JSON(), nullable=False),
        sa.Column("n_samples", sa.BigInteger(), nullable=False),
        sa.Column("time_offset_s", sa.Float(), nullable=False),
        sa.Column("alignment", sa.Text(), nullable=False),
        sa.Column("t_start", sa.Float(), nullable=True),
        sa.Column("t_end", sa.Float(), nullable=True),
        sa.Column("trials", sa.JSON(), nullable=False),
        sa.Column("size_bytes", sa.BigInteger(), nullable=False),
        sa.Column("sha256", sa.String(length=64), nullable=False),
        sa.Column("quality", sa.JSON(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(["session_id"], ["study_sessions.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["montage_id"], ["emg_montages.id"], ondelete="RESTRICT"),
        sa.ForeignKeyConstraint(["stream_id"], ["emg_streams.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_emg_recordings_session_id", "emg_recordings", ["session_id"])
    op.create_table(
        "mvc_steps",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("session_id", sa.Integer(), nullable=False),
        sa.Column("planned_order", sa.Integer(), nullable=False),
        sa.Column("muscle", sa.String(length=40), nullable=False),
        sa.Column("side", sa.String(length=8), nullable=False),
        sa.Column("repetitions", sa.Integer(), nullable=False),
        sa.Column("rest_s", sa.Float(), nullable=False),
        sa.Column("contraction_s", sa.Float(), nullable=False),
        sa.Column("repetitions_done", sa.JSON(), nullable=False),
        sa.Column("created_at", _tz(), nullable=False),
        sa.ForeignKeyConstraint(["session_id"], ["study_sessions.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_mvc_steps_session_id", "mvc_steps", ["session_id"])


def downgrade() -> None:
    op.drop_index("ix_mvc_steps_session_id", table_name="mvc_steps")
    op.drop_table("mvc_steps")
    op.drop_index("ix_emg_recordings_session_id", table_name="emg_recordings")
    op.drop_table("emg_recordings")
    op.drop_index("ix_emg_streams_session_id", table_name="emg_streams")
    op.drop_table("emg_streams")
    op.drop_table("emg_analysis_settings")
    op.drop_index("ix_emg_montages_study_id", table_name="emg_montages")
    op.drop_table("emg_montages")
