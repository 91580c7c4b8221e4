"""XDF import: a file written here (pyxdf's reader as the oracle of the writer) is
attached to a session, its streams are put on ExoStudy's clock and matched to trials;
bad files are refused with a 422 naming the file; the CLI's BIDS export carries it."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import pyxdf
from fastapi.testclient import TestClient
from sqlalchemy import insert
from sqlalchemy.orm import Session

from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.db.models import Participant, Run, Study, StudySession, ticks_table
from backend.lab.lsl_outlets import TICK_CHANNEL_NAMES
from controller.tick_record import TickRecord
from tests.backend.lab.xdf_writer import XdfStream, write_xdf

#: ExoStudy's LSL clock minus Unix time in the made-up session (a machine up ~10 min).
LSL_MINUS_UNIX = 600.0 - 1.7e9
#: The LabRecorder computer's clock minus ExoStudy's: another host, 1000.25 s apart.
FILE_SHIFT = 1000.25


def _ticks(run_id: int, seq0: int, t_host0: float, n: int) -> list[dict[str, Any]]:
    rows = []
    for i in range(n):
        r = TickRecord(seq=seq0 + i, t=i / 100, t_host=t_host0 + i / 100,
                       q_left=0.5 * math.sin(i / 40), q_right=0.4 * math.sin(i / 40),
                       lock_left=150 <= i < 220, lock_right=150 <= i < 220)
        d = {k: (None if isinstance(v, float) and v != v else v)
             for k, v in r.as_dict().items()}
        d["run_id"] = run_id
        rows.append(d)
    return rows


def _session_with_two_trials(db_url: str) -> dict[str, Any]:
    """A session whose two trials ran 10 s apart, each with start and stop markers."""
    engine = make_engine(db_url)
    out: dict[str, Any] = {"trials": [], "ticks": []}
    with Session(engine) as db:
        study = Study(name="Lab study")
        db.add(study)
        db.flush()
        p = Participant(study_id=study.id, code="P01", age=31, sex="female", height_m=1.68,
                        mass_kg=61.0, notes="private note")
        db.add(p)
        db.flush()
        sess = StudySession(participant_id=p.id, kind="evaluation", precompression_pct=25.0)
        db.add(sess)
        db.flush()
        for k, (task, start) in enumerate((("squat-sequence", 1.7e9 + 5.0),
                                           ("stoop-sequence", 1.7e9 + 20.0))):
            run = Run(device_kind="sim", controller="pec")
            db.add(run)
            db.flush()
            trial = Trial(session_id=sess.id, controller="pec", task=task, planned_order=k,
                          status="completed", run_id=run.id)
            db.add(trial)
            db.flush()
            rows = _ticks(run.id, 1000 * (k + 1), start, 300)
            db.execute(insert(ticks_table), rows)
            for label, i in (("trial_start", 0), ("trial_stop", 299)):
                db.add(Marker(session_id=sess.id, trial_id=trial.id, run_id=run.id,
                              t=rows[i]["t"], lsl_time=rows[i]["t_host"] + LSL_MINUS_UNIX,
                              label=label, note="", source="system"))
            db.add(Marker(session_id=sess.id, trial_id=trial.id, run_id=run.id, t=1.5,
                          lsl_time=start + 1.5 + LSL_MINUS_UNIX, label="box dropped",
                          note="", source="console"))
            out["trials"].append(trial.id)
            out["ticks"].append(rows)
        db.commit()
        out["study"], out["session"] = study.id, sess.id
    engine.dispose()
    return out


def _xdf(ticks: list[dict[str, Any]]) -> tuple[bytes, list[XdfStream]]:
    """The first trial's ticks as LabRecorder on another host would have them, a motion
    capture stream over the same 3 s, and a marker stream."""
    lsl = [r["t_host"] + LSL_MINUS_UNIX + FILE_SHIFT for r in ticks]
    exo = XdfStream("ExoStudy", "ExoskeletonTicks", list(TICK_CHANNEL_NAMES), 100.0,
                    "double64", lsl,
                    [[float(r[c] or 0.0) for c in TICK_CHANNEL_NAMES] for r in ticks],
                    source_id="exostudy-ticks", clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    n = 600
    mocap = XdfStream("Mocap", "MoCap", ["pelvis_x", "pelvis_y", "pelvis_z"], 200.0,
                      "double64", [lsl[0] + i / 200 for i in range(n)],
                      [[0.01 * i, 1.0, -0.5] for i in range(n)],
                      clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    marks = XdfStream("ForcePlateMarkers", "Markers", ["event"], 0.0, "string",
                      [lsl[50], lsl[120]], [["heel strike"], ["toe off"]],
                      clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    streams = [exo, mocap, marks]
    return write_xdf(streams), streams


def test_the_writer_is_read_back_by_pyxdf(tmp_path: Path) -> None:
    ticks = _ticks(1, 10, 1.7e9, 200)
    data, written = _xdf(ticks)
    path = tmp_path / "check.xdf"
    path.write_bytes(data)
    streams, _ = pyxdf.load_xdf(str(path), dejitter_timestamps=False)
    by_name = {s["info"]["name"][0]: s for s in streams}
    assert set(by_name) == {"ExoStudy", "Mocap", "ForcePlateMarkers"}
    for w in written:
        got = by_name[w.name]
        np.testing.assert_allclose(got["time_stamps"], w.stamps, rtol=0, atol=1e-9)
        if w.fmt == "string":
            assert got["time_series"] == w.rows
        else:
            np.testing.assert_array_equal(np.asarray(got["time_series"]), np.asarray(w.rows))


def test_an_xdf_file_is_aligned_with_the_trials(client: TestClient, db_url: str,
                                                tmp_path: Path) -> None:
    made = _session_with_two_trials(db_url)
    data, _ = _xdf(made["ticks"][0])
    sid = made["session"]
    r = client.post(f"/api/sessions/{sid}/xdf",
                    files={"file": ("lab-recording.xdf", data, "application/octet-stream")})
    assert r.status_code == 201, r.text
    att = r.json()
    assert att["size_bytes"] == len(data) and att["filename"] == "lab-recording.xdf"
    streams = {s["name"]: s for s in att["streams"]}
    first, second = made["trials"]
    exo = streams["ExoStudy"]
    assert exo["exostudy"] and exo["samples"] == 300 and exo["channel_count"] == 15
    # The file's clock is found 1000.25 s ahead of ours, to well under a millisecond.
    assert exo["offset_ms"] == pytest.approx(FILE_SHIFT * 1000.0, abs=1e-3)
    assert exo["trial_ids"] == [first]
    assert streams["Mocap"]["trial_ids"] == [first]
    assert streams["Mocap"]["channels"] == ["pelvis_x", "pelvis_y", "pelvis_z"]
    assert streams["ForcePlateMarkers"]["trial_ids"] == [first] and second not in \
        streams["ForcePlateMarkers"]["trial_ids"]
    # Kept byte for byte.
    assert client.get(f"/api/sessions/{sid}/xdf/{att['id']}/file").content == data
    assert [a["id"] for a in client.get(f"/api/sessions/{sid}/xdf").json()] == [att["id"]]

    # A file that is not XDF, or is cut short, is a 422 naming the file; nothing stored.
    for bad in (b"PK\x03\x04 not xdf", data[: len(data) // 3]):
        r = client.post(f"/api/sessions/{sid}/xdf",
                        files={"file": ("broken.xdf", bad, "application/octet-stream")})
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "file"]
    assert len(client.get(f"/api/sessions/{sid}/xdf").json()) == 1
    assert client.post("/api/sessions/999999/xdf", files={
        "file": ("a.xdf", data, "application/octet-stream")}).status_code == 404


def test_cli_bids_export_carries_trials_markers_and_the_xdf(
        client: TestClient, db_url: str, tmp_path: Path) -> None:
    from backend.cli import main
    from tests.backend.lab.bids_validator import validate

    made = _session_with_two_trials(db_url)
    data, _ = _xdf(made["ticks"][0])
    assert client.post(f"/api/sessions/{made['session']}/xdf", files={
        "file": ("lab.xdf", data, "application/octet-stream")}).status_code == 201
    out = tmp_path / "bids"
    assert main(["export", "--study", str(made["study"]), "--bids", str(out),
                 "--db", db_url]) == 0
    assert validate(out) == []
    motion = sorted(out.glob("sub-P01/ses-*/motion/*_motion.tsv"))
    assert len(motion) == 2
    # One row per stored tick, no header, the channels in _channels.tsv's order.
    rows = [line.split("\t") for line in motion[0].read_text().splitlines()]
    assert len(rows) == 300
    names = [line.split("\t")[0] for line in
             Path(str(motion[0]).replace("_motion.tsv", "_channels.tsv")).read_text()
             .splitlines()[1:]]
    stored = made["ticks"][0]
    for i in (0, 123, 299):
        assert float(rows[i][names.index("q_left")]) == stored[i]["q_left"]
        assert int(rows[i][names.index("lock_left")]) == int(stored[i]["lock_left"])
    events = next(out.glob("sub-P01/ses-*/motion/*task-squatsequence*_events.tsv"))
    ev = [line.split("\t") for line in events.read_text().splitlines()]
    assert ev[0][:3] == ["onset", "duration", "trial_type"]
    assert ["1.5", "0.0", "marker", "n/a", "box dropped", "console"] in [e[:6] for e in ev]
    participants = (out / "participants.tsv").read_text()
    assert "sub-P01" in participants and "private note" not in participants
    assert len(list(out.glob("sourcedata/sub-P01/ses-*/*.xdf"))) == 1
    # A second export into the same folder is refused rather than mixed in.
    assert main(["export", "--study", str(made["study"]), "--bids", str(out),
                 "--db", db_url]) == 2
    with tempfile.TemporaryDirectory() as empty:
        assert main(["export", "--study", "999", "--bids", empty, "--db", db_url]) == 2
