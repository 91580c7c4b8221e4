"""Background jobs that survive a restart: who queued a job, its lane, when it started.

`created_by` lets the server limit each account's queued cohorts; `lane` says which
runner thread takes the job (`study`: model fits and utilities, short; `cohort`: virtual
cohorts, long), so a fit is never queued behind cohorts; `started_at` is when it left
the queue. An index on `status` serves the start-up reconciliation and the per-account
count. Existing cohort jobs are put in the `cohort` lane.

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-26 00:40:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0012"
down_revision = "0011"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.add_column(sa.Column("lane", sa.String(length=16), nullable=False,
                                      server_default="study"))
        batch_op.add_column(sa.Column("started_at", sa.DateTime(timezone=True),
                                      nullable=True))
        batch_op.add_column(sa.Column("created_by", sa.Integer(), nullable=True))
        batch_op.create_foreign_key("fk_jobs_created_by", "users", ["created_by"], ["id"],
                                    ondelete="SET NULL")
        batch_op.create_index("ix_jobs_status", ["status"], unique=False)
    op.execute("UPDATE jobs SET lane = 'cohort' WHERE kind = 'cohort'")


def downgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.drop_index("ix_jobs_status")
        batch_op.drop_constraint("fk_jobs_created_by", type_="foreignkey")
        batch_op.drop_column("created_by")
        batch_op.drop_column("started_at")
        batch_op.drop_column("lane")
