"""No export hands a spreadsheet a formula (CSV injection, OWASP): text typed into
ExoStudy (participant and session notes, recording labels and notes, marker labels and
notes) that starts with =, +, -, @, tab or carriage return comes out with a leading
single quote in every CSV and TSV export, and numbers stay numbers."""

from __future__ import annotations

import csv
import io
import zipfile

from fastapi.testclient import TestClient

from controller.evaluation.tables import Table
from controller.spreadsheet import FORMULA_STARTS
from tests.backend.export_study import FORMULAS, make_study


def _cells(text: str, delimiter: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text), delimiter=delimiter))


def _number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def assert_no_formula(name: str, text: str, delimiter: str = ",") -> None:
    """Every cell of the file reads as data in a spreadsheet."""
    for r, row in enumerate(_cells(text, delimiter)):
        for c, cell in enumerate(row):
            assert not (cell.startswith(FORMULA_STARTS) and not _number(cell)), \
                f"{name} row {r} column {c}: {cell!r}"


def _csv_files(zf: zipfile.ZipFile) -> dict[str, str]:
    return {n: zf.read(n).decode() for n in zf.namelist() if n.endswith((".csv", ".tsv"))}


def test_the_full_export_neutralises_every_formula(client: TestClient, db_url: str) -> None:
    ids = make_study(client, db_url)
    r = client.get(f"/api/studies/{ids['study']}/export.zip")
    assert r.status_code == 200, r.text
    files = _csv_files(zipfile.ZipFile(io.BytesIO(r.content)))
    for name, text in files.items():
        assert_no_formula(name, text)

    def column(file: str, col: str) -> list[str]:
        return [row[col] for row in csv.DictReader(io.StringIO(files[file]))]

    assert column("participants.csv", "notes") == ["'" + FORMULAS["participant_notes"]]
    assert column("study_sessions.csv", "notes") == ["'" + FORMULAS["session_notes"]]
    assert column("recordings.csv", "label") == ["'" + FORMULAS["recording_label"]]
    assert column("recordings.csv", "notes") == ["'" + FORMULAS["recording_notes"]]
    assert "'" + FORMULAS["marker_label"] in column("markers.csv", "label")
    assert "'" + FORMULAS["marker_note"] in column("markers.csv", "note")
    # Numbers stay numbers: negative hip angles in the ticks, negative times nowhere
    # quoted.
    ticks = _cells(files[f"ticks/trial-{ids['trial']}.csv"], ",")
    q_right = [float(row[ticks[0].index("q_right")]) for row in ticks[1:]]
    assert min(q_right) < 0


def test_the_deidentified_export_neutralises_every_formula(client: TestClient,
                                                           db_url: str) -> None:
    ids = make_study(client, db_url)
    r = client.get(f"/api/studies/{ids['study']}/export-deidentified.zip")
    assert r.status_code == 200, r.text
    for name, text in _csv_files(zipfile.ZipFile(io.BytesIO(r.content))).items():
        assert_no_formula(name, text)


def test_the_bids_events_neutralise_marker_text(client: TestClient, db_url: str) -> None:
    ids = make_study(client, db_url)
    r = client.get(f"/api/studies/{ids['study']}/export.bids.zip")
    assert r.status_code == 200, r.text
    files = _csv_files(zipfile.ZipFile(io.BytesIO(r.content)))
    for name, text in files.items():
        assert_no_formula(name, text, "\t")
    events = next(t for n, t in files.items() if n.endswith("_events.tsv"))
    values = [row[4] for row in _cells(events, "\t")[1:]]
    # The marker's label and note, one cell: quoted, and the tab inside made a space
    # (BIDS' TSV has no quoting, so a tab would split the cell).
    assert "'" + FORMULAS["marker_label"] + ": " + FORMULAS["marker_note"].replace(
        "\t", " ") in values
    onsets = [float(row[0]) for row in _cells(events, "\t")[1:]]
    assert onsets == sorted(onsets) and 1.0 in onsets


def test_results_csvs_neutralise_text_cells_and_keep_numbers() -> None:
    table = Table(("participant", "note", "value"),
                  (("P01", "=1+1", -1.5), ("P02", "@x", 2.0), ("-P03", "fine", -0.25)))
    rows = _cells(table.to_csv(), ",")
    assert rows == [["participant", "note", "value"], ["P01", "'=1+1", "-1.5"],
                    ["P02", "'@x", "2.0"], ["'-P03", "fine", "-0.25"]]


def test_the_results_endpoints_write_no_formula(client: TestClient, db_url: str) -> None:
    from backend.analysis.results import TABLE_NAMES

    ids = make_study(client, db_url)
    for table in TABLE_NAMES:
        r = client.get(f"/api/studies/{ids['study']}/results/{table}.csv")
        assert r.status_code in (200, 409), r.text
        if r.status_code == 200:
            assert_no_formula(table, r.text)
