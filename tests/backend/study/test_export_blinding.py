"""Exports keep the blinding key for the study's owner and keep de-identification
stable: an experimenter's de-identified and BIDS downloads hold blinded labels only
(no `A,umc` row, no scans row naming both), the owner's hold both; the date shift is
the participant's stored one at every download; marker labels that may be free text
are replaced; the data dictionary says which export holds what."""

from __future__ import annotations

import csv
import fnmatch
import io
import json
import zipfile
from datetime import date

from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.db.engine import make_engine
from backend.db.models import Participant
from tests.backend.export_study import make_study
from tests.login import bearer, create_experimenter

OTHER = {"username": "analyst", "password": "a long passphrase for the analyst"}


def _as_experimenter(client: TestClient, db_url: str, study: int) -> dict[str, str]:
    create_experimenter(db_url, **OTHER)
    r = client.put(f"/api/studies/{study}/members",
                   json={"username": OTHER["username"], "role": "experimenter"})
    assert r.status_code == 200, r.text
    return bearer(TestClient(client.app), OTHER)


def _zip(content: bytes) -> dict[str, str]:
    zf = zipfile.ZipFile(io.BytesIO(content))
    return {n: zf.read(n).decode("utf-8", "replace") for n in zf.namelist()
            if not n.endswith(".xdf")}


def _rows(text: str, delimiter: str = ",") -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text), delimiter=delimiter))


def test_an_experimenters_exports_hold_blinded_labels_only(client: TestClient,
                                                           db_url: str) -> None:
    ids = make_study(client, db_url)
    h = _as_experimenter(client, db_url, ids["study"])
    other = TestClient(client.app)

    deid = _zip(other.get(f"/api/studies/{ids['study']}/export-deidentified.zip",
                          headers=h).content)
    labels = _rows(deid["condition_labels.csv"])
    assert [(r["label"], r["controller"]) for r in labels] == [("A", "")]
    bids = other.get(f"/api/studies/{ids['study']}/export.bids.zip", headers=h)
    assert bids.status_code == 200, bids.text
    files = _zip(bids.content)
    assert not any("pec" in name for name in files), sorted(files)
    scans = next(t for n, t in files.items() if n.endswith("_scans.tsv"))
    [row] = _rows(scans, "\t")
    assert row["blinded_label"] == "A" and "controller" not in row and "trial_id" not in row
    assert "_acq-A_" in row["filename"]
    motion = next(t for n, t in files.items() if n.endswith("_motion.json"))
    assert "pec" not in motion

    # The owner's downloads unblind.
    deid = _zip(client.get(f"/api/studies/{ids['study']}/export-deidentified.zip").content)
    assert [(r["label"], r["controller"])
            for r in _rows(deid["condition_labels.csv"])] == [("A", "pec")]
    files = _zip(client.get(f"/api/studies/{ids['study']}/export.bids.zip").content)
    scans = next(t for n, t in files.items() if n.endswith("_scans.tsv"))
    [row] = _rows(scans, "\t")
    assert (row["controller"], row["blinded_label"]) == ("pec", "A")
    assert row["trial_id"] == str(ids["trial"])


def test_the_date_shift_is_stored_and_the_same_at_every_download(
        client: TestClient, db_url: str) -> None:
    ids = make_study(client, db_url)
    engine = make_engine(db_url)
    with engine.connect() as conn:
        stored = conn.execute(select(Participant.date_shift_days).where(
            Participant.id == ids["participant"])).scalar_one()
    engine.dispose()
    assert 1 <= stored <= 364
    downloads = [_zip(client.get(f"/api/studies/{ids['study']}/export-deidentified.zip")
                      .content) for _ in range(3)]
    dates = {_rows(d["participants.csv"])[0]["consent_date"] for d in downloads}
    assert len(dates) == 1
    shifted = date.fromisoformat(dates.pop())
    assert (date(2026, 3, 2) - shifted).days == stored
    sessions = {_rows(d["study_sessions.csv"])[0]["started_at"] for d in downloads}
    assert len(sessions) == 1
    # The shift itself never leaves.
    assert "date_shift_days" not in downloads[0]["participants.csv"].splitlines()[0]


def test_free_text_marker_labels_are_replaced_in_the_deidentified_export(
        client: TestClient, db_url: str) -> None:
    ids = make_study(client, db_url)
    files = _zip(client.get(f"/api/studies/{ids['study']}/export-deidentified.zip").content)
    labels = sorted(r["label"] for r in _rows(files["markers.csv"]))
    # The system's label and the study's marker button stay; typed or LSL text goes.
    assert labels == ["box dropped", "other", "other", "trial_start"]
    assert all(r["note"] == "" for r in _rows(files["markers.csv"]))
    assert "ouch" not in "".join(files.values())
    dictionary = {(d["file"], d["column"]): d["deidentified"]
                  for d in _rows(files["data_dictionary.csv"])}
    assert "other" in dictionary[("markers.csv", "label")]
    assert "owner" in dictionary[("condition_labels.csv", "controller")]
    assert "stored" in dictionary[("participants.csv", "consent_date")]


def test_the_dictionary_says_which_export_holds_what_and_the_sidecars_agree(
        client: TestClient, db_url: str) -> None:
    from backend.analysis import bids_dictionary, data_dictionary

    ids = make_study(client, db_url)
    readme = _zip(client.get(f"/api/studies/{ids['study']}/export.zip").content)["README.md"]
    assert "## Which export holds what" in readme
    for name, _who, _what in data_dictionary.EXPORTS:
        assert f"| {name} |" in readme
    files = _zip(client.get(f"/api/studies/{ids['study']}/export.bids.zip").content)

    checked = 0
    for pattern, (_about, cols) in bids_dictionary.BIDS_FILES.items():
        tsv = next((n for n in files if fnmatch.fnmatch(n.split("/", 1)[1], pattern)
                    or fnmatch.fnmatch(n.rsplit("/", 1)[1], pattern)), None)
        if tsv is None:
            continue  # (no questionnaire answers in this study)
        checked += 1
        sidecar = json.loads(files[tsv.removesuffix(".tsv") + ".json"])
        header = files[tsv].splitlines()[0].split("\t")
        for col in header:
            if col == "HED":
                continue
            # Every column is described, in the dictionary's own words.
            assert sidecar[col]["Description"] == cols[col][1], (tsv, col)
            assert f"| {col} | {cols[col][0]} | {cols[col][1]} |" in readme
    assert checked == 3
