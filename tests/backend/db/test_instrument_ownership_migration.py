"""Migration 0011: instruments that were global attach to the study that used them,
with a copy per study when several did; links get the row they resolve to; nothing
stored is lost, and the database stays consistent on SQLite and PostgreSQL."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import JSON, Connection, inspect, text

from backend.db import migrate
from backend.db.engine import make_engine

NOW = datetime(2026, 11, 1, tzinfo=UTC)


def _definition(key: str, version: str) -> str:
    return json.dumps({"key": key, "version": version, "title": key,
                       "items": [{"id": "x", "text": "?"}], "scale": {"min": 0, "max": 10},
                       "aggregation": {"method": "sum"}, "score_range": {"min": 0, "max": 10},
                       "provenance": {"wording": "study"}})


def _insert(conn: Connection, table: str, **values: Any) -> int:
    # Columns later revisions made required get a plain value, so the seed does not
    # depend on what they are.
    for col in inspect(conn).get_columns(table):
        if (col["name"] not in values and not col["nullable"] and col["default"] is None
                and col["name"] != "id"):
            values[col["name"]] = "{}" if isinstance(col["type"], JSON) else 1
    cols = ", ".join(values)
    marks = ", ".join(f":{k}" for k in values)
    return int(conn.execute(text(f"INSERT INTO {table} ({cols}) VALUES ({marks}) RETURNING id"),
                            values).scalar_one())


def _json(value: Any) -> Any:
    """JSON columns read with plain SQL: text on SQLite, decoded on PostgreSQL."""
    return json.loads(value) if isinstance(value, str) else value


def _seed(conn: Connection) -> dict[str, int]:
    ids: dict[str, int] = {}
    for name in ("alice", "bob", "carol"):
        ids[name] = _insert(conn, "users", username=name, password_hash="x", active=True,
                            created_at=NOW, role="member", password_published=False)
    for name, owner in (("S1", "alice"), ("S2", "bob"), ("S3", "bob")):
        ids[name] = _insert(conn, "studies", name=name, description="",
                            created_by=ids[owner], created_at=NOW, withdrawal_policy="erase")
        conn.execute(text("INSERT INTO study_members (study_id, user_id, role, created_at) "
                          "VALUES (:s, :u, 'owner', :t)"),
                     {"s": ids[name], "u": ids[owner], "t": NOW})
    for code, study in (("P1", "S1"), ("P2", "S2")):
        ids[code] = _insert(conn, "participants", study_id=ids[study], code=code, notes="",
                            created_at=NOW)
    inst = {"key": "", "version": "1", "title": "t", "built_in": False, "created_at": NOW}
    # Used by S1 and S2 (a response in each); used nowhere, creator alice (only S1);
    # used nowhere, creator bob (S2 and S3): no study can be told.
    ids["shared"] = _insert(conn, "questionnaire_instruments", **{
        **inst, "key": "shared", "definition": _definition("shared", "1"),
        "created_by": ids["carol"]})
    ids["alices"] = _insert(conn, "questionnaire_instruments", **{
        **inst, "key": "alices", "definition": _definition("alices", "1"),
        "created_by": ids["alice"]})
    ids["orphan"] = _insert(conn, "questionnaire_instruments", **{
        **inst, "key": "orphan", "definition": _definition("orphan", "1"),
        "created_by": ids["bob"]})
    for code in ("P1", "P2"):
        form = {"instrument_key": "shared", "instrument_version": "1", "condition_label": None}
        link = _insert(conn, "participant_links", participant_id=ids[code],
                       token_hash=f"hash-{code}", forms_due=json.dumps([form]),
                       preference_due=False, created_at=NOW,
                       expires_at=NOW + timedelta(days=1))
        ids[f"link-{code}"] = link
        ids[f"resp-{code}"] = _insert(
            conn, "questionnaire_responses", participant_id=ids[code], link_id=link,
            instrument_id=ids["shared"], instrument_key="shared", instrument_version="1",
            answers=json.dumps({"x": 3}), score=3.0, subscale_scores="{}",
            submitted_at=NOW, link_form=0)
    return ids


def test_0011_attaches_copies_and_pins(db_url: str) -> None:
    migrate.upgrade(db_url, "0010")
    engine = make_engine(db_url)
    with engine.begin() as conn:
        ids = _seed(conn)
    migrate.upgrade(db_url, "0011")
    with engine.connect() as conn:
        rows = {(r.key, r.study_id): r for r in conn.execute(text(
            "SELECT id, key, version, study_id, built_in, definition "
            "FROM questionnaire_instruments WHERE NOT built_in"))}
        resp = {r.id: r.instrument_id for r in conn.execute(text(
            "SELECT id, instrument_id FROM questionnaire_responses"))}
        links = {r.id: r.forms_due for r in conn.execute(text(
            "SELECT id, forms_due FROM participant_links"))}
    engine.dispose()
    # The shared instrument: the oldest study keeps the row, the other gets a copy.
    assert rows[("shared", ids["S1"])].id == ids["shared"]
    copy = rows[("shared", ids["S2"])]
    assert copy.id != ids["shared"]
    assert _json(copy.definition) == json.loads(_definition("shared", "1"))
    assert resp == {ids["resp-P1"]: ids["shared"], ids["resp-P2"]: copy.id}
    pinned = {lid: _json(f)[0]["instrument_id"]
              for lid, f in links.items()}
    assert pinned == {ids["link-P1"]: ids["shared"], ids["link-P2"]: copy.id}
    # Unused: the creator's only study; a creator in two studies: no study (kept).
    assert rows[("alices", ids["S1"])].id == ids["alices"]
    assert rows[("orphan", None)].id == ids["orphan"]
    assert len(rows) == 4


def test_0011_down_and_up_again_without_shared_rows(db_url: str) -> None:
    migrate.upgrade(db_url)
    migrate.downgrade(db_url, "0010")
    migrate.upgrade(db_url)
