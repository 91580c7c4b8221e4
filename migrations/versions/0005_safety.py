"""Safety of the lock command: one running trial or recording, interrupted trials, run closing.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-22 20:05:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # A database left by a killed server may hold several "running" rows; keep the
    # newest and mark the others interrupted so the unique indexes can be built.
    op.execute("UPDATE trials SET status = 'interrupted', end_reason = 'server stopped' "
               "WHERE status = 'running' AND id < (SELECT max(id) FROM trials "
               "WHERE status = 'running')")
    op.execute("UPDATE recordings SET status = 'interrupted' WHERE status = 'recording' "
               "AND id < (SELECT max(id) FROM recordings WHERE status = 'recording')")
    with op.batch_alter_table("trials", schema=None) as batch_op:
        batch_op.add_column(sa.Column("tick_count", sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column("quality_flags", sa.JSON(), nullable=True))
        batch_op.create_index("uq_trials_one_running", ["status"], unique=True,
                              sqlite_where=sa.text("status = 'running'"),
                              postgresql_where=sa.text("status = 'running'"))
    # Issue 12 item 2: why a tick's sample was implausible (`Plausibility` bits); an
    # added column, so SQLite adds it in place (old ticks read NULL: not checked).
    with op.batch_alter_table("ticks", schema=None) as batch_op:
        batch_op.add_column(sa.Column("plausibility", sa.BigInteger(), nullable=True))
    with op.batch_alter_table("recordings", schema=None) as batch_op:
        batch_op.create_index("uq_recordings_one_running", ["status"], unique=True,
                              sqlite_where=sa.text("status = 'recording'"),
                              postgresql_where=sa.text("status = 'recording'"))


def downgrade() -> None:
    with op.batch_alter_table("ticks", schema=None) as batch_op:
        batch_op.drop_column("plausibility")
    with op.batch_alter_table("recordings", schema=None) as batch_op:
        batch_op.drop_index("uq_recordings_one_running")
    with op.batch_alter_table("trials", schema=None) as batch_op:
        batch_op.drop_index("uq_trials_one_running")
        batch_op.drop_column("quality_flags")
        batch_op.drop_column("tick_count")
