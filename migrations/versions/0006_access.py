"""Access control: roles, study membership, sites, consent versions, login throttling.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-22 20:05:00
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("users", schema=None) as batch_op:
        batch_op.add_column(sa.Column("role", sa.String(length=16), nullable=False,
                                      server_default="member"))
        batch_op.add_column(sa.Column("password_published", sa.Boolean(), nullable=False,
                                      server_default=sa.false()))
    with op.batch_alter_table("studies", schema=None) as batch_op:
        batch_op.add_column(sa.Column("withdrawal_policy", sa.String(length=16),
                                      nullable=False, server_default="erase"))
    with op.batch_alter_table("participants", schema=None) as batch_op:
        batch_op.add_column(sa.Column("site", sa.String(length=64), nullable=True))
        batch_op.add_column(sa.Column("consent_version", sa.String(length=32), nullable=True))
        batch_op.add_column(sa.Column("withdrawn_at", sa.DateTime(timezone=True),
                                      nullable=True))
    op.create_table(
        "study_members",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("role", sa.String(length=16), nullable=False),
        sa.Column("site", sa.String(length=64), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["study_id"], ["studies.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("study_id", "user_id", name="uq_study_members"),
    )
    with op.batch_alter_table("study_members", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_study_members_study_id"), ["study_id"])
        batch_op.create_index(batch_op.f("ix_study_members_user_id"), ["user_id"])
    # Existing studies keep working: their creator becomes their owner.
    op.execute("INSERT INTO study_members (study_id, user_id, role, created_at) "
               "SELECT id, created_by, 'owner', created_at FROM studies "
               "WHERE created_by IS NOT NULL")
    # Existing accounts were all-powerful; the oldest becomes the administrator.
    op.execute("UPDATE users SET role = 'admin' WHERE id = (SELECT MIN(id) FROM users)")
    op.create_table(
        "consent_documents",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("version", sa.String(length=32), nullable=False),
        sa.Column("text", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["study_id"], ["studies.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("study_id", "version", name="uq_consent_version"),
    )
    with op.batch_alter_table("consent_documents", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_consent_documents_study_id"), ["study_id"])
    op.create_table(
        "login_failures",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("username", sa.String(length=64), nullable=False),
        sa.Column("address", sa.String(length=64), nullable=False),
        sa.PrimaryKeyConstraint("id"),
    )
    with op.batch_alter_table("login_failures", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_login_failures_at"), ["at"])
        batch_op.create_index(batch_op.f("ix_login_failures_username"), ["username"])
        batch_op.create_index(batch_op.f("ix_login_failures_address"), ["address"])
    # Single-use links, atomically: the database refuses a second response to one form
    # of a link, and a second preference on a link.
    with op.batch_alter_table("questionnaire_responses", schema=None) as batch_op:
        batch_op.add_column(sa.Column("link_form", sa.Integer(), nullable=True))
        batch_op.create_unique_constraint("uq_responses_link_form", ["link_id", "link_form"])
    with op.batch_alter_table("preferences", schema=None) as batch_op:
        batch_op.create_unique_constraint("uq_preferences_link", ["link_id"])


def downgrade() -> None:
    with op.batch_alter_table("preferences", schema=None) as batch_op:
        batch_op.drop_constraint("uq_preferences_link", type_="unique")
    with op.batch_alter_table("questionnaire_responses", schema=None) as batch_op:
        batch_op.drop_constraint("uq_responses_link_form", type_="unique")
        batch_op.drop_column("link_form")
    op.drop_table("login_failures")
    op.drop_table("consent_documents")
    op.drop_table("study_members")
    with op.batch_alter_table("participants", schema=None) as batch_op:
        batch_op.drop_column("withdrawn_at")
        batch_op.drop_column("consent_version")
        batch_op.drop_column("site")
    with op.batch_alter_table("studies", schema=None) as batch_op:
        batch_op.drop_column("withdrawal_policy")
    with op.batch_alter_table("users", schema=None) as batch_op:
        batch_op.drop_column("password_published")
        batch_op.drop_column("role")
