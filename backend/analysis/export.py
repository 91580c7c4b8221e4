"""A whole study as one zip: every table as CSV, model and utility documents as JSON,
every trial's and recording's ticks, and a data dictionary. Everything a reanalysis needs,
nothing that identifies a person or an account secret."""

from __future__ import annotations

import io
import json
import secrets
import zipfile
from collections.abc import Sequence
from datetime import date, datetime, timedelta
from typing import Any

from sqlalchemy import Engine, Table, or_, select

from backend.analysis import data_dictionary, tick_queries
from backend.analysis.data_dictionary import EXPORTED_COLUMNS, EXPORTED_TABLES
from backend.core.resources import version
from backend.db.tables import Base
from controller import spreadsheet
from controller.tick_record import TICK_FIELD_DOCS, TickRecord


def _table(name: str) -> Table:
    return Base.metadata.tables[name]


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


#: What the de-identified export does to a column (the data dictionary says it too).
#: Direct identifiers and free text go; dates move by a per-participant offset; ages
#: above 89 are reported as 90 (the HIPAA Safe Harbor rule's age bound).
DEID_BLANK = {"notes", "created_by", "end_reason", "message", "error"}
#: Free text that only some tables have under a common name.
DEID_BLANK_IN = {("recordings", "label"), ("markers", "note")}
#: Marker labels the de-identified export keeps: the system's own; any other label is
#: kept only if it is one of the study's marker buttons (a vocabulary fixed before any
#: participant came), else it may be free text (an LSL sample, a typed label) and is
#: replaced by `MARKER_OTHER`.
SYSTEM_MARKER_LABELS = frozenset({"trial_start", "trial_stop"})
MARKER_OTHER = "other"
DEID_NOTE = {
    "code": "replaced by a new pseudonym (R001, R002, ...) that no key links back",
    "age": "ages above 89 are reported as 90",
    **{c: "removed (free text or account id)" for c in DEID_BLANK},
}
_DATE_SHIFT_NOTE = ("shifted by a random whole number of days (1-364) earlier, the same "
                    "for all of one participant's rows (intervals stay true) and at every "
                    "download (drawn once and stored with the participant)")
_MARKER_LABEL_NOTE = ("kept if trial_start, trial_stop or one of the study's marker buttons; "
                      f"any other text replaced by \"{MARKER_OTHER}\"")
_BLINDING_NOTE = "the blinding key: empty unless the download was made by the study's owner"


def _parent_maps(conn: Any, sessions: list[int], recordings: list[int], trials: list[int]
                 ) -> dict[str, dict[int, int]]:
    """Participant of each session, recording and trial."""
    st, rt, tt = _table("study_sessions"), _table("recordings"), _table("trials")
    of_session = {r[0]: r[1] for r in conn.execute(
        select(st.c.id, st.c.participant_id).where(st.c.id.in_(sessions or [-1])))}
    of_recording = {r[0]: of_session[r[1]] for r in conn.execute(
        select(rt.c.id, rt.c.session_id).where(rt.c.id.in_(recordings or [-1])))}
    of_trial = {r[0]: of_session[r[1]] for r in conn.execute(
        select(tt.c.id, tt.c.session_id).where(tt.c.id.in_(trials or [-1])))}
    return {"session_id": of_session, "recording_id": of_recording, "trial_id": of_trial}


def _shift(v: Any, days: int) -> Any:
    if isinstance(v, datetime | date):
        return v - timedelta(days=days)
    return v


def study_zip(engine: Engine, study_id: int, deidentified: bool = False,
              site: str | None = None, unblind: bool = False,
              muscle_files: Sequence[tuple[str, str]] = ()) -> bytes:
    """The export archive of one study (withdrawn-and-excluded participants are left
    out). `deidentified`: without direct identifiers and free text, participants
    re-coded, dates shifted by each participant's stored shift (see `DEID_NOTE`).
    `site`: only that site's participants, for a member limited to it. `unblind`: the
    blinding key (which controller each label stands for) is written; only an owner's
    export may set it, anyone else's leaves the `controller` of condition_labels empty.
    `muscle_files`: (name, text) written under `muscle_activity/` of an unblinded,
    identified export (the tables name controllers and codes); the caller reads them
    from the stored EMG (`backend.emg.muscle_results.export_files`), a layer above this
    one."""
    rng = secrets.SystemRandom()
    buf = io.BytesIO()
    with engine.connect() as conn, zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        pt = _table("participants")
        participants = [r[0] for r in conn.execute(
            select(pt.c.id).where(pt.c.study_id == study_id, pt.c.withdrawn_at.is_(None),
                                  *([pt.c.site == site] if site is not None else []))
            .order_by(pt.c.id))]
        sessions = _ids(conn, "study_sessions", "participant_id", participants)
        recordings = _ids(conn, "recordings", "session_id", sessions)
        trials = _ids(conn, "trials", "session_id", sessions)
        parents = _parent_maps(conn, sessions, recordings, trials)
        shift = {r[0]: r[1] for r in conn.execute(
            select(pt.c.id, pt.c.date_shift_days).where(pt.c.id.in_(participants or [-1])))}
        st = _table("studies")
        study_shift = conn.execute(select(st.c.date_shift_days)
                                   .where(st.c.id == study_id)).scalar_one_or_none() or 0
        buttons = _marker_buttons(conn, study_id)
        recode = {pid: f"R{i:03d}" for i, pid in enumerate(rng.sample(participants,
                                                                        len(participants)), 1)}
        scope: dict[str, tuple[str, list[int]]] = {
            "participants": ("id", participants),
            "study_sessions": ("participant_id", participants),
            "condition_labels": ("participant_id", participants),
            "recordings": ("session_id", sessions),
            "lift_segments": ("recording_id", recordings),
            "model_sets": ("study_id", [study_id]),
            "utility_sets": ("study_id", [study_id]),
            "prior_sets": ("participant_id", participants),
            "trials": ("session_id", sessions),
            "trial_segments": ("trial_id", trials),
            "lock_events": ("trial_id", trials),
            "questionnaire_responses": ("participant_id", participants),
            "preferences": ("participant_id", participants),
            "markers": ("session_id", sessions),
            "xdf_attachments": ("session_id", sessions),
        }
        for name in EXPORTED_TABLES:
            column, keys = scope[name]
            t = _table(name)
            cols = EXPORTED_COLUMNS[name]
            out = io.StringIO()
            w = spreadsheet.writer(out)
            w.writerow(cols)
            if keys:
                q = select(*(t.c[c] for c in cols), t.c[column]).where(
                    t.c[column].in_(keys), *_of_included(t, participants)).order_by(t.c.id)
                for *row, key in conn.execute(q):
                    if deidentified:
                        row = _deidentify(name, cols, row, key, column, parents, shift,
                                          study_shift, recode, buttons)
                    if not unblind and name == "condition_labels":
                        row[cols.index("controller")] = None
                    w.writerow([_cell(v) for v in row])
            zf.writestr(f"{name}.csv", out.getvalue())
        for name in ("model_sets", "utility_sets", "prior_sets"):
            t = _table(name)
            for rid, doc in conn.execute(select(t.c.id, t.c.document)
                                         .where(t.c.study_id == study_id,
                                                *_of_included(t, participants))):
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
        readme = data_dictionary.markdown()
        if deidentified:
            readme = ("# De-identified export\n\nParticipant codes are replaced, free text "
                      "and account ids removed, ages above 89 reported as 90, and every date "
                      "shifted per participant; `data_dictionary.csv` says what was done to "
                      "each column (column `deidentified`).\n\n" + readme)
        zf.writestr("README.md", readme + f"\nExported by ExoStudy {version()}.\n")
        zf.writestr("data_dictionary.csv", _dictionary_csv(deidentified))
        if unblind and not deidentified:  # muscle tables name controllers and codes
            for name, text in muscle_files:
                zf.writestr(f"muscle_activity/{name}", text)
    return buf.getvalue()


def _of_included(t: Table, participants: list[int]) -> list[Any]:
    """Extra conditions on a study-wide table whose rows may belong to one participant
    (personal model sets, prior sets): only those of the exported participants."""
    if "participant_id" not in t.c:
        return []
    return [or_(t.c.participant_id.is_(None), t.c.participant_id.in_(participants or [-1]))]


def _marker_buttons(conn: Any, study_id: int) -> frozenset[str]:
    """The study's marker buttons (labels fixed for the whole study)."""
    t = _table("study_marker_labels")
    labels = conn.execute(select(t.c.labels).where(t.c.study_id == study_id)).scalar()
    return frozenset(str(x) for x in labels or [])


def _deidentify(table: str, cols: list[str], row: list[Any], key: int, column: str,
                parents: dict[str, dict[int, int]], shift: dict[int, int], study_shift: int,
                recode: dict[int, str], buttons: frozenset[str] = frozenset()) -> list[Any]:
    """One row as the de-identified export writes it."""
    if column in ("id", "participant_id"):
        pid: int | None = key
    else:
        pid = parents.get(column, {}).get(key)
    days = shift[pid] if pid is not None else study_shift
    out = []
    for c, v in zip(cols, row, strict=True):
        if c in DEID_BLANK or (table, c) in DEID_BLANK_IN:
            v = None
        elif table == "participants" and c == "code" and pid is not None:
            v = recode[pid]
        elif table == "markers" and c == "label":
            v = v if v in SYSTEM_MARKER_LABELS or v in buttons else MARKER_OTHER
        elif c == "age" and isinstance(v, int) and v > 89:
            v = 90
        else:
            v = _shift(v, days)
        out.append(v)
    return out


def _dictionary_csv(deidentified: bool = False) -> str:
    out = io.StringIO()
    w = spreadsheet.writer(out)
    w.writerow(["file", "column", "unit", "meaning"] + (["deidentified"] if deidentified
                                                        else []))
    for name in EXPORTED_TABLES:
        types = {c.name: _python_type(c.type) for c in _table(name).columns}
        for col in EXPORTED_COLUMNS[name]:
            unit, meaning = data_dictionary.describe(name, col)
            extra = []
            if deidentified:
                note = DEID_NOTE.get(col, "")
                if (name, col) in DEID_BLANK_IN:
                    note = "removed (free text)"
                if (name, col) == ("markers", "label"):
                    note = _MARKER_LABEL_NOTE
                if (f"{name}.csv", col) in data_dictionary.BLINDING_KEY:
                    note = _BLINDING_NOTE
                if not note and types.get(col) in (date, datetime):
                    note = _DATE_SHIFT_NOTE
                if name != "participants" and col == "code":
                    note = ""
                extra = [note or "unchanged"]
            w.writerow([f"{name}.csv", col, unit, meaning, *extra])
    for col in TickRecord.field_names():
        unit, meaning = TICK_FIELD_DOCS[col]
        w.writerow(["ticks/*.csv", col, unit, meaning] + (["unchanged"] if deidentified
                                                           else []))
    return out.getvalue()


def _python_type(t: Any) -> type | None:
    try:
        found: type = t.python_type
        return found
    except NotImplementedError:
        return None
