"""A whole study as one zip: every table as CSV, model and utility documents as JSON,
every trial's and recording's ticks, and a data dictionary. Everything a reanalysis needs,
nothing that identifies a person or an account secret."""

from __future__ import annotations

import csv
import io
import json
import zipfile
from datetime import date, datetime
from typing import Any

from sqlalchemy import Engine, Table, select

from backend import data_dictionary, tick_queries
from backend.db.tables import Base

#: Columns left out of the CSVs: large documents (written as JSON files instead).
_OMIT = {"document", "human_data"}

_TABLE_ORDER = ("participants", "study_sessions", "condition_labels", "recordings",
                "lift_segments", "model_sets", "utility_sets", "trials", "trial_segments",
                "lock_events", "questionnaire_responses", "preferences")


def _table(name: str) -> Table:
    return Base.metadata.tables[name]


EXPORTED_COLUMNS: dict[str, list[str]] = {
    name: [c.name for c in _table(name).columns if c.name not in _OMIT] for name in _TABLE_ORDER
}


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, datetime | date):
        return v.isoformat()
    if isinstance(v, dict | list):
        return json.dumps(v, sort_keys=True)
    if isinstance(v, bool):
        return int(v)
    return v


def _ids(conn: Any, table: str, column: str, keys: list[int]) -> list[int]:
    if not keys:
        return []
    t = _table(table)
    return [r[0] for r in conn.execute(select(t.c.id).where(t.c[column].in_(keys)))]


def study_zip(engine: Engine, study_id: int) -> bytes:
    """The export archive of one study."""
    buf = io.BytesIO()
    with engine.connect() as conn, zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        participants = _ids(conn, "participants", "study_id", [study_id])
        sessions = _ids(conn, "study_sessions", "participant_id", participants)
        recordings = _ids(conn, "recordings", "session_id", sessions)
        trials = _ids(conn, "trials", "session_id", sessions)
        scope: dict[str, tuple[str, list[int]]] = {
            "participants": ("study_id", [study_id]),
            "study_sessions": ("participant_id", participants),
            "condition_labels": ("participant_id", participants),
            "recordings": ("session_id", sessions),
            "lift_segments": ("recording_id", recordings),
            "model_sets": ("study_id", [study_id]),
            "utility_sets": ("study_id", [study_id]),
            "trials": ("session_id", sessions),
            "trial_segments": ("trial_id", trials),
            "lock_events": ("trial_id", trials),
            "questionnaire_responses": ("participant_id", participants),
            "preferences": ("participant_id", participants),
        }
        for name in _TABLE_ORDER:
            column, keys = scope[name]
            t = _table(name)
            cols = EXPORTED_COLUMNS[name]
            out = io.StringIO()
            w = csv.writer(out, lineterminator="\n")
            w.writerow(cols)
            if keys:
                q = select(*(t.c[c] for c in cols)).where(t.c[column].in_(keys)).order_by(t.c.id)
                for row in conn.execute(q):
                    w.writerow([_cell(v) for v in row])
            zf.writestr(f"{name}.csv", out.getvalue())
        for name in ("model_sets", "utility_sets"):
            t = _table(name)
            for rid, doc in conn.execute(select(t.c.id, t.c.document)
                                         .where(t.c.study_id == study_id)):
                if doc is not None:
                    zf.writestr(f"{name}/{rid}.json", json.dumps(doc, indent=1))
        runs = [("trial", r[0], r[1], None, None) for r in conn.execute(
            select(_table("trials").c.id, _table("trials").c.run_id)
            .where(_table("trials").c.id.in_(trials or [-1])))]
        rt = _table("recordings")
        runs += [("recording", r[0], r[1], r[2], r[3]) for r in conn.execute(
            select(rt.c.id, rt.c.run_id, rt.c.first_tick_id, rt.c.last_tick_id)
            .where(rt.c.id.in_(recordings or [-1])))]
    with zipfile.ZipFile(buf, "a", zipfile.ZIP_DEFLATED) as zf:
        for kind, rid, run_id, first, last in runs:
            if run_id is not None:
                zf.writestr(f"ticks/{kind}-{rid}.csv",
                            tick_queries.csv_text(engine, run_id, first, last))
        zf.writestr("README.md", data_dictionary.markdown())
        zf.writestr("data_dictionary.csv", _dictionary_csv())
    return buf.getvalue()


def _dictionary_csv() -> str:
    from controller.tick import TICK_FIELD_DOCS, TickRecord

    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["file", "column", "unit", "meaning"])
    for name in _TABLE_ORDER:
        for col in EXPORTED_COLUMNS[name]:
            unit, meaning = data_dictionary.describe(name, col)
            w.writerow([f"{name}.csv", col, unit, meaning])
    for col in TickRecord.field_names():
        unit, meaning = TICK_FIELD_DOCS[col]
        w.writerow(["ticks/*.csv", col, unit, meaning])
    return out.getvalue()
