"""Personal model sets and prior sets (issue 30).

Model sets gain their kind (population or personal), method (ppca or map), the wearer
of a personal set and the population set it adapts; `prior_sets` holds each
participant's versioned priors; trials gain their condition (the blinding key), which
models it runs (population or personal), its prior set and, for a demonstration block,
the demonstrations it asks for. Existing rows read as before: population models fitted
by PPCA, trials whose condition is their controller with equal priors.

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-27 00:10:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0016"
down_revision = "0015"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("model_sets", schema=None) as batch_op:
        batch_op.add_column(sa.Column("kind", sa.String(length=16), nullable=False,
                                      server_default="population"))
        batch_op.add_column(sa.Column("method", sa.String(length=32), nullable=False,
                                      server_default="ppca"))
        batch_op.add_column(sa.Column("participant_id", sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column("base_model_set_id", sa.Integer(), nullable=True))
        batch_op.create_foreign_key("fk_model_sets_participant_id", "participants",
                                    ["participant_id"], ["id"], ondelete="CASCADE")
        batch_op.create_foreign_key("fk_model_sets_base_model_set_id", "model_sets",
                                    ["base_model_set_id"], ["id"], ondelete="SET NULL")
        batch_op.create_index("ix_model_sets_participant_id", ["participant_id"])
    op.create_table(
        "prior_sets",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("method", sa.String(length=32), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("utility_set_id", sa.Integer(), nullable=True),
        sa.Column("previous_id", sa.Integer(), nullable=True),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("document", sa.JSON(), nullable=True),
        sa.Column("error", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(["study_id"], ["studies.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["participant_id"], ["participants.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["utility_set_id"], ["utility_sets.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["previous_id"], ["prior_sets.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("participant_id", "version",
                            name="uq_prior_sets_participant_version"),
    )
    op.create_index("ix_prior_sets_study_id", "prior_sets", ["study_id"])
    op.create_index("ix_prior_sets_participant_id", "prior_sets", ["participant_id"])
    with op.batch_alter_table("trials", schema=None) as batch_op:
        batch_op.add_column(sa.Column("condition", sa.String(length=64), nullable=False,
                                      server_default=""))
        batch_op.add_column(sa.Column("models", sa.String(length=16), nullable=False,
                                      server_default="population"))
        batch_op.add_column(sa.Column("prior_set_id", sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column("demonstrations", sa.JSON(), nullable=True))
        batch_op.create_foreign_key("fk_trials_prior_set_id", "prior_sets",
                                    ["prior_set_id"], ["id"], ondelete="SET NULL")


def downgrade() -> None:
    with op.batch_alter_table("trials", schema=None) as batch_op:
        batch_op.drop_constraint("fk_trials_prior_set_id", type_="foreignkey")
        batch_op.drop_column("demonstrations")
        batch_op.drop_column("prior_set_id")
        batch_op.drop_column("models")
        batch_op.drop_column("condition")
    op.drop_index("ix_prior_sets_participant_id", table_name="prior_sets")
    op.drop_index("ix_prior_sets_study_id", table_name="prior_sets")
    op.drop_table("prior_sets")
    with op.batch_alter_table("model_sets", schema=None) as batch_op:
        batch_op.drop_index("ix_model_sets_participant_id")
        batch_op.drop_constraint("fk_model_sets_base_model_set_id", type_="foreignkey")
        batch_op.drop_constraint("fk_model_sets_participant_id", type_="foreignkey")
        batch_op.drop_column("base_model_set_id")
        batch_op.drop_column("participant_id")
        batch_op.drop_column("method")
        batch_op.drop_column("kind")
