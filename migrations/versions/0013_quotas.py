"""Quotas and throttles that hold under concurrency.

`login_throttles` counts each account's and each address's login attempts in their
current window; an attempt is counted by one conditional UPDATE before its password is
checked, so concurrent wrong passwords cannot all slip past a check that came before
their failures were stored. `jobs.quota_slot` is the slot (0..limit-1) an unfinished job
limited per account holds; the unique index on (created_by, kind, quota_slot) lets the
database refuse a job beyond the limit however close together the requests come.
Finished jobs hold no slot (null), so existing jobs keep none.

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-26 21:00:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0013"
down_revision = "0012"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "login_throttles",
        sa.Column("key", sa.String(length=80), nullable=False),
        sa.Column("window_start", sa.DateTime(timezone=True), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.PrimaryKeyConstraint("key"),
    )
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.add_column(sa.Column("quota_slot", sa.Integer(), nullable=True))
        batch_op.create_unique_constraint("uq_jobs_quota_slot",
                                          ["created_by", "kind", "quota_slot"])


def downgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.drop_constraint("uq_jobs_quota_slot", type_="unique")
        batch_op.drop_column("quota_slot")
    op.drop_table("login_throttles")
