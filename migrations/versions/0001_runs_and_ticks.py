"""Runs and ticks: the stream of control ticks, one row per tick.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("ended_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("device_kind", sa.String(length=32), nullable=False),
        sa.Column("controller", sa.String(length=32), nullable=False),
        sa.Column("config_json", sa.Text(), nullable=False),
        sa.Column("worker_pid", sa.Integer(), nullable=True),
        sa.Column("end_reason", sa.String(length=200), nullable=True),
        sa.Column("tick_count", sa.BigInteger(), nullable=False),
    )
    op.create_table(
        "ticks",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("run_id", sa.Integer(), sa.ForeignKey("runs.id", ondelete="CASCADE"),
                  nullable=False),
        sa.Column("seq", sa.BigInteger(), nullable=True),
        sa.Column("t", sa.Float(), nullable=True),
        sa.Column("t_host", sa.Float(), nullable=True),
        sa.Column("count_left_output", sa.BigInteger(), nullable=True),
        sa.Column("count_left_cam", sa.BigInteger(), nullable=True),
        sa.Column("count_right_output", sa.BigInteger(), nullable=True),
        sa.Column("count_right_cam", sa.BigInteger(), nullable=True),
        sa.Column("q_raw_left", sa.Float(), nullable=True),
        sa.Column("q_raw_right", sa.Float(), nullable=True),
        sa.Column("q_left", sa.Float(), nullable=True),
        sa.Column("q_right", sa.Float(), nullable=True),
        sa.Column("omega_left", sa.Float(), nullable=True),
        sa.Column("omega_right", sa.Float(), nullable=True),
        sa.Column("trigger", sa.Boolean(), nullable=True),
        sa.Column("controller_ran", sa.Boolean(), nullable=True),
        sa.Column("d_squat", sa.Float(), nullable=True),
        sa.Column("l_squat", sa.BigInteger(), nullable=True),
        sa.Column("s_start_squat", sa.Float(), nullable=True),
        sa.Column("s_curr_squat", sa.Float(), nullable=True),
        sa.Column("accepted_squat", sa.Boolean(), nullable=True),
        sa.Column("p_obs_squat", sa.Float(), nullable=True),
        sa.Column("d_stoop_left", sa.Float(), nullable=True),
        sa.Column("l_stoop_left", sa.BigInteger(), nullable=True),
        sa.Column("s_start_stoop_left", sa.Float(), nullable=True),
        sa.Column("s_curr_stoop_left", sa.Float(), nullable=True),
        sa.Column("accepted_stoop_left", sa.Boolean(), nullable=True),
        sa.Column("p_obs_stoop_left", sa.Float(), nullable=True),
        sa.Column("d_stoop_right", sa.Float(), nullable=True),
        sa.Column("l_stoop_right", sa.BigInteger(), nullable=True),
        sa.Column("s_start_stoop_right", sa.Float(), nullable=True),
        sa.Column("s_curr_stoop_right", sa.Float(), nullable=True),
        sa.Column("accepted_stoop_right", sa.Boolean(), nullable=True),
        sa.Column("p_obs_stoop_right", sa.Float(), nullable=True),
        sa.Column("post_squat", sa.Float(), nullable=True),
        sa.Column("post_stoop_left", sa.Float(), nullable=True),
        sa.Column("post_stoop_right", sa.Float(), nullable=True),
        sa.Column("post_other", sa.Float(), nullable=True),
        sa.Column("eu_no_lock", sa.Float(), nullable=True),
        sa.Column("eu_lock_both", sa.Float(), nullable=True),
        sa.Column("eu_lock_right", sa.Float(), nullable=True),
        sa.Column("eu_lock_left", sa.Float(), nullable=True),
        sa.Column("action", sa.BigInteger(), nullable=True),
        sa.Column("lock_left", sa.Boolean(), nullable=True),
        sa.Column("lock_right", sa.Boolean(), nullable=True),
        sa.Column("locked_left", sa.Boolean(), nullable=True),
        sa.Column("locked_right", sa.Boolean(), nullable=True),
        sa.Column("alpha_left", sa.Float(), nullable=True),
        sa.Column("alpha_right", sa.Float(), nullable=True),
        sa.Column("torque_left", sa.Float(), nullable=True),
        sa.Column("torque_right", sa.Float(), nullable=True),
        sa.Column("flags", sa.BigInteger(), nullable=True),
        sa.Column("compute_us", sa.Float(), nullable=True),
        sa.Column("truth_activity", sa.String(length=32), nullable=True),
        sa.Column("truth_lift", sa.BigInteger(), nullable=True),
        sa.Column("truth_progress", sa.Float(), nullable=True),
    )
    op.create_index("ix_ticks_run_t", "ticks", ["run_id", "t"])


def downgrade() -> None:
    op.drop_index("ix_ticks_run_t", table_name="ticks")
    op.drop_table("ticks")
    op.drop_table("runs")
