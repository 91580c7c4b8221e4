"""Questionnaire instruments belong to a study; participant links pin the instrument row;
a marker stream subscription can be closed as failed.

Before this revision every imported instrument was global: an experimenter of one study
could import `sus` version 9.9 and a link of another study that named no version got it.
Now built-in instruments stay global (no study) and immutable, and every other
instrument belongs to one study (`study_id`).

Existing custom instruments are attached as follows (nothing is deleted):

- used (by a response or a link) in exactly one study: that study;
- used in several studies: the oldest study keeps the row, every other study gets its
  own copy (same key, version and definition), and its responses and links are moved
  onto the copy, so each study's records point at its own row;
- used nowhere: the only study its creator belongs to (member or creator);
- otherwise (no creator, or a creator in several studies or none): kept with no study
  and `built_in` false, which no link can use; an administrator can read it in the
  database and a study can import it again under its own name.

Every form of every existing link gets the id of the instrument row it resolves to
(`instrument_id`), so a participant's form is served from exactly that row.

SQLite cannot drop the old `UNIQUE (key, version)` without rebuilding the table, and
rebuilding a table that other rows reference fails while foreign keys are enforced;
the rebuild follows SQLite's documented procedure (foreign keys off outside a
transaction, rebuild, `PRAGMA foreign_key_check`, foreign keys on). With foreign keys
on, SQLite's `DROP TABLE` of the old copy would refuse (responses point at it) or, for
a table whose children cascade, delete the children.

`lab_marker_streams.error` says why the server closed a subscription (a name the LSL
resolver cannot search for, or an inlet that kept failing); existing rows get "".

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-26 00:30:00
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import sqlalchemy as sa
from alembic import op

revision = "0011"
down_revision = "0010"
branch_labels = None
depends_on = None

_instruments = sa.table(
    "questionnaire_instruments", sa.column("id", sa.Integer), sa.column("key", sa.String),
    sa.column("version", sa.String), sa.column("title", sa.String),
    sa.column("definition", sa.JSON), sa.column("built_in", sa.Boolean),
    sa.column("created_by", sa.Integer), sa.column("created_at", sa.DateTime(timezone=True)),
    sa.column("study_id", sa.Integer))
_participants = sa.table("participants", sa.column("id", sa.Integer),
                         sa.column("study_id", sa.Integer))
_links = sa.table("participant_links", sa.column("id", sa.Integer),
                  sa.column("participant_id", sa.Integer), sa.column("forms_due", sa.JSON))
_responses = sa.table("questionnaire_responses", sa.column("id", sa.Integer),
                      sa.column("participant_id", sa.Integer),
                      sa.column("instrument_id", sa.Integer))
_members = sa.table("study_members", sa.column("study_id", sa.Integer),
                    sa.column("user_id", sa.Integer))
_studies = sa.table("studies", sa.column("id", sa.Integer), sa.column("created_by", sa.Integer))


@contextmanager
def _foreign_keys_off() -> Iterator[None]:
    """On SQLite, rebuild with foreign keys off. If the migration environment has not
    switched them off already, this revision does: the pragma is ignored inside a
    transaction, so what ran before is committed first."""
    bind = op.get_bind()
    if bind.dialect.name != "sqlite" or not bind.exec_driver_sql(
            "PRAGMA foreign_keys").scalar():
        yield
        return
    bind.commit()
    bind.exec_driver_sql("PRAGMA foreign_keys=OFF")
    try:
        yield
        problems = bind.exec_driver_sql("PRAGMA foreign_key_check").fetchall()
        if problems:
            raise RuntimeError(f"0011 left broken references: {problems[:5]}")
        bind.commit()
    finally:
        bind.exec_driver_sql("PRAGMA foreign_keys=ON")


def _schema_up() -> None:
    with _foreign_keys_off(), op.batch_alter_table("questionnaire_instruments") as batch:
        batch.add_column(sa.Column("study_id", sa.Integer(), nullable=True))
        batch.create_foreign_key("fk_questionnaire_instruments_study_id", "studies",
                                 ["study_id"], ["id"], ondelete="CASCADE")
        batch.drop_constraint("uq_instruments_key_version", type_="unique")
        batch.create_unique_constraint("uq_instruments_study_key_version",
                                       ["study_id", "key", "version"])
    op.create_index("ix_questionnaire_instruments_study_id", "questionnaire_instruments",
                    ["study_id"])
    op.create_index("uq_instruments_builtin_key_version", "questionnaire_instruments",
                    ["key", "version"], unique=True, sqlite_where=sa.text("built_in"),
                    postgresql_where=sa.text("built_in"))


def _studies_of_creator(bind: sa.Connection, user_id: int | None) -> set[int]:
    if user_id is None:
        return set()
    ids = set(bind.scalars(sa.select(_members.c.study_id).where(_members.c.user_id == user_id)))
    ids |= set(bind.scalars(sa.select(_studies.c.id).where(_studies.c.created_by == user_id)))
    return ids


def _data_up() -> None:
    bind = op.get_bind()
    study_of = {pid: sid for pid, sid in bind.execute(
        sa.select(_participants.c.id, _participants.c.study_id))}
    rows = list(bind.execute(sa.select(_instruments)).mappings())
    built_in = {(r["key"], r["version"]): r["id"] for r in rows if r["built_in"]}
    custom = {(r["key"], r["version"]): dict(r) for r in rows if not r["built_in"]}
    links = [(lid, pid, list(forms or [])) for lid, pid, forms in bind.execute(
        sa.select(_links.c.id, _links.c.participant_id, _links.c.forms_due))]
    used: dict[int, set[int]] = {r["id"]: set() for r in custom.values()}
    for iid, pid in bind.execute(sa.select(_responses.c.instrument_id,
                                           _responses.c.participant_id)):
        if iid in used and pid in study_of:
            used[iid].add(study_of[pid])
    for _link, owner, forms in links:
        for form in forms:
            found = custom.get((form.get("instrument_key"), form.get("instrument_version")))
            if found is not None and owner in study_of:
                used[found["id"]].add(study_of[owner])
    # (key, version, study) -> the row that study's forms and responses now use.
    row_for: dict[tuple[str, str, int], int] = {}
    for (key, version), row in custom.items():
        studies = sorted(used[row["id"]])
        if not studies:
            owners = _studies_of_creator(bind, row["created_by"])
            studies = sorted(owners) if len(owners) == 1 else []
        if not studies:
            continue  # kept, attached to no study: served to nobody
        bind.execute(sa.update(_instruments).where(_instruments.c.id == row["id"])
                     .values(study_id=studies[0]))
        row_for[(key, version, studies[0])] = row["id"]
        for study in studies[1:]:
            copy_id = bind.execute(sa.insert(_instruments).values(
                key=key, version=version, title=row["title"], definition=row["definition"],
                built_in=False, created_by=row["created_by"], created_at=row["created_at"],
                study_id=study).returning(_instruments.c.id)).scalar_one()
            row_for[(key, version, study)] = copy_id
            members = [p for p, s in study_of.items() if s == study]
            if members:
                bind.execute(sa.update(_responses).where(
                    _responses.c.instrument_id == row["id"],
                    _responses.c.participant_id.in_(members)).values(instrument_id=copy_id))
    for lid, pid, forms in links:
        link_study = study_of.get(pid)
        changed = []
        for form in forms:
            kv = (form.get("instrument_key"), form.get("instrument_version"))
            pinned: int | None = built_in.get(kv)
            if pinned is None and link_study is not None:
                pinned = row_for.get((*kv, link_study))
            changed.append({**form, "instrument_id": pinned})
        if changed != forms:
            bind.execute(sa.update(_links).where(_links.c.id == lid)
                         .values(forms_due=changed))


def upgrade() -> None:
    _schema_up()
    _data_up()
    with op.batch_alter_table("lab_marker_streams") as batch:
        batch.add_column(sa.Column("error", sa.Text(), nullable=False, server_default=""))


def downgrade() -> None:
    bind = op.get_bind()
    dupes = list(bind.execute(sa.select(_instruments.c.key, _instruments.c.version)
                              .group_by(_instruments.c.key, _instruments.c.version)
                              .having(sa.func.count() > 1)))
    if dupes:
        # One global (key, version) cannot hold two studies' rows; merging them would
        # change what some responses were scored with.
        raise RuntimeError(f"cannot downgrade below 0011: instruments {dupes[:5]} exist in "
                           "more than one study")
    with _foreign_keys_off(), op.batch_alter_table("lab_marker_streams") as batch:
        batch.drop_column("error")  # markers point at these rows: a rebuild
    op.drop_index("uq_instruments_builtin_key_version", "questionnaire_instruments")
    op.drop_index("ix_questionnaire_instruments_study_id", "questionnaire_instruments")
    with _foreign_keys_off(), op.batch_alter_table("questionnaire_instruments") as batch:
        batch.drop_constraint("uq_instruments_study_key_version", type_="unique")
        batch.drop_constraint("fk_questionnaire_instruments_study_id", type_="foreignkey")
        batch.drop_column("study_id")
        batch.create_unique_constraint("uq_instruments_key_version", ["key", "version"])
