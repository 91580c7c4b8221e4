"""Bring-up bound to its device, and device rights from a lab grant (issue 27).

Hardware profiles record the unique id the device proves in its CHALLENGE and, for a
draft, when it expires; `device_grants` holds the accounts an administrator allowed to
use the exoskeleton. Profiles made before keep an empty unique id, so they match no
device: bring-up must be done again on protocol 3 (no profile is applied by guess).

Revision ID: 0014
Revises: 0013
Create Date: 2026-12-02 00:40:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0014"
down_revision = "0013"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("hardware_profiles", schema=None) as batch_op:
        batch_op.add_column(sa.Column("unique_id", sa.String(length=32), nullable=False,
                                      server_default=""))
        batch_op.add_column(sa.Column("expires_at", sa.DateTime(timezone=True),
                                      nullable=True))
    op.create_table(
        "device_grants",
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("granted_by", sa.Integer(), nullable=True),
        sa.Column("granted_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["granted_by"], ["users.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("user_id"),
    )


def downgrade() -> None:
    op.drop_table("device_grants")
    with op.batch_alter_table("hardware_profiles", schema=None) as batch_op:
        batch_op.drop_column("expires_at")
        batch_op.drop_column("unique_id")
