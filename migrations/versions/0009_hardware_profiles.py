"""Hardware profiles, and the profile in effect on every session and trial.

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-26 00:40:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "hardware_profiles",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("device", sa.String(length=16), nullable=False),
        sa.Column("firmware_version", sa.String(length=200), nullable=False),
        sa.Column("key_id", sa.String(length=16), nullable=False),
        sa.Column("precompression_pct", sa.Float(), nullable=False),
        sa.Column("encoder_offsets", sa.JSON(), nullable=False),
        sa.Column("encoder_directions", sa.JSON(), nullable=False),
        sa.Column("cam_output_offsets", sa.JSON(), nullable=False),
        sa.Column("steps", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("completed_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
    )
    for table in ("study_sessions", "trials"):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.add_column(sa.Column("hardware_profile_id", sa.Integer(), nullable=True))
            batch_op.create_foreign_key(f"fk_{table}_hardware_profile_id", "hardware_profiles",
                                        ["hardware_profile_id"], ["id"], ondelete="SET NULL")


def downgrade() -> None:
    for table in ("trials", "study_sessions"):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.drop_constraint(f"fk_{table}_hardware_profile_id", type_="foreignkey")
            batch_op.drop_column("hardware_profile_id")
    op.drop_table("hardware_profiles")
