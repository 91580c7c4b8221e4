"""Exports: one stored date shift per participant (and per study) for the de-identified
export, and the study's dataset description (authors, licence, institution) for BIDS.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-26 00:30:00
"""

from __future__ import annotations

import secrets

import sqlalchemy as sa
from alembic import op

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None

#: The largest shift in days (as `backend.db.models.MAX_SHIFT_DAYS`; a migration keeps
#: its own copy so that it never changes with the code).
MAX_SHIFT_DAYS = 364


def _draw_shifts(table: str) -> None:
    """A shift for every existing row, drawn once and kept from now on."""
    conn = op.get_bind()
    t = sa.table(table, sa.column("id", sa.Integer), sa.column("date_shift_days", sa.Integer))
    for (row_id,) in conn.execute(sa.select(t.c.id)).all():
        conn.execute(t.update().where(t.c.id == row_id)
                     .values(date_shift_days=secrets.randbelow(MAX_SHIFT_DAYS) + 1))


def upgrade() -> None:
    for table in ("participants", "studies"):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.add_column(sa.Column("date_shift_days", sa.Integer(), nullable=True))
        _draw_shifts(table)
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.alter_column("date_shift_days", existing_type=sa.Integer(),
                                  nullable=False)
    with op.batch_alter_table("studies", schema=None) as batch_op:
        batch_op.add_column(sa.Column("dataset_info", sa.JSON(), nullable=True))
    op.execute("UPDATE studies SET dataset_info = '{}'")
    with op.batch_alter_table("studies", schema=None) as batch_op:
        batch_op.alter_column("dataset_info", existing_type=sa.JSON(), nullable=False)


def downgrade() -> None:
    with op.batch_alter_table("studies", schema=None) as batch_op:
        batch_op.drop_column("dataset_info")
        batch_op.drop_column("date_shift_days")
    with op.batch_alter_table("participants", schema=None) as batch_op:
        batch_op.drop_column("date_shift_days")
