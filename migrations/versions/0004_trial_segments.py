"""Trial segments: the experimenter's lifts in a trial, the ground truth on hardware.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-22 10:50:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "trial_segments",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("trial_id", sa.Integer(), nullable=False),
        sa.Column("start", sa.Integer(), nullable=False),
        sa.Column("peak", sa.Integer(), nullable=False),
        sa.Column("end", sa.Integer(), nullable=False),
        sa.Column("label", sa.String(length=32), nullable=False),
        sa.Column("source", sa.String(length=16), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["trial_id"], ["trials.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
    )
    with op.batch_alter_table("trial_segments", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_trial_segments_trial_id"), ["trial_id"],
                              unique=False)


def downgrade() -> None:
    with op.batch_alter_table("trial_segments", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_trial_segments_trial_id"))
    op.drop_table("trial_segments")
