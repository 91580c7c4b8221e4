"""A trial's EMG panel through the API: the stored envelope over the trial, decimated,
with the trial's lifts and their outcomes; a trial without EMG, or one that has not
run, is a 409 saying why."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import edfio
import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from backend.db.emg import EmgRecording
from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from tests.backend.lab.test_xdf_import import _session_with_two_trials

FS = 2000.0
MONTAGE: dict[str, Any] = {"channels": [
    {"label": "ES-L", "muscle": "erector_spinae_lumbar", "side": "left"},
    {"label": "ES-R", "muscle": "erector_spinae_lumbar", "side": "right"},
]}
#: ES-L: a steady 100 Hz sine. Its envelope is 2 A / pi (the band-pass passes 100 Hz
#: with gain 1 within 0.1 %, the 6 Hz low-pass leaves the 200 Hz ripple below 1e-6).
AMPLITUDE_UV = 300.0
LEVEL_V = 2 * AMPLITUDE_UV / np.pi * 1e-6


def _edf(tmp: Path, seconds: float) -> bytes:
    n = int(seconds * FS)
    t = np.arange(n) / FS
    data = [AMPLITUDE_UV * np.sin(2 * np.pi * 100 * t),
            np.random.default_rng(1).normal(0, 30.0, n)]
    signals = [edfio.EdfSignal(d, FS, label=c["label"], physical_dimension="uV",
                               physical_range=(-1000.0, 1000.0))
               for d, c in zip(data, MONTAGE["channels"], strict=True)]
    edfio.Edf(signals).write(tmp / "a.edf")
    return (tmp / "a.edf").read_bytes()


def test_the_envelope_over_a_trial_with_its_lifts(client: TestClient, db_url: str,
                                                  tmp_path: Path) -> None:
    made = _session_with_two_trials(db_url)
    first, second = made["trials"]
    assert client.put(f"/api/studies/{made['study']}/emg-montage", json=MONTAGE).is_success
    r = client.get(f"/api/trials/{first}/emg-envelope")
    assert r.status_code == 409
    assert f"trial {first} has no EMG: none of the 0 EMG recordings" in r.json()["detail"]
    assert client.put(f"/api/trials/{first}/segments", json=[
        {"start": 40, "peak": 90, "end": 140, "label": "squat"}]).is_success
    r = client.post(f"/api/sessions/{made['session']}/emg/edf",
                    files={"file": ("a.edf", _edf(tmp_path, 6.0))},
                    data={"trial": str(first), "offset_s": "-1.5"})
    assert r.status_code == 201, r.text

    r = client.get(f"/api/trials/{first}/emg-envelope", params={"points": 300})
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["recording_id"] and doc["source"] == "edf" and doc["unit"] == "V"
    assert doc["processing"]["envelope_hz"] == 6.0 and doc["normalisation"] == "none"
    assert [c["label"] for c in doc["channels"]] == ["ES-L", "ES-R"]
    # The trial's 3 s (300 ticks), from its start, at most 300 points.
    assert len(doc["t"]) <= 300 and doc["fs"] == pytest.approx(FS / 20)
    assert doc["t"][0] == pytest.approx(0.0, abs=1 / FS)
    assert doc["t"][-1] == pytest.approx(doc["duration_s"], abs=0.02)
    assert doc["duration_s"] == pytest.approx(2.99, abs=1e-6)
    es_l = np.asarray(doc["channels"][0]["values"])
    np.testing.assert_allclose(es_l, LEVEL_V, rtol=0.01)  # the padding kept edges clean
    assert doc["lift_source"] == "segments"
    (lift,) = doc["lifts"]
    assert (lift["kind"], lift["start_s"], lift["end_s"]) == ("squat", pytest.approx(0.4),
                                                              pytest.approx(1.4))
    assert lift["peak"][0] == pytest.approx(LEVEL_V, rel=0.01)
    assert lift["mean"][0] == pytest.approx(LEVEL_V, rel=0.01)
    assert lift["iemg"][0] == pytest.approx(LEVEL_V * 1.0, rel=0.01)

    # The same recording left by a killed server (finalised as interrupted) is shown too.
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        row = db.get(EmgRecording, doc["recording_id"])
        assert row is not None
        row.status = "interrupted"
        db.commit()
    again = client.get(f"/api/trials/{first}/emg-envelope", params={"points": 300})
    assert again.status_code == 200, again.text
    assert again.json()["channels"] == doc["channels"]
    # Its file gone (deleted by hand, a disk fault): a 409 that names it, not a 500.
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        row = db.get(EmgRecording, doc["recording_id"])
        assert row is not None
        moved = client.app.state.settings.emg_dir / f"{row.id}.emgc"  # type: ignore[attr-defined]
    moved.rename(moved.with_suffix(".away"))
    gone = client.get(f"/api/trials/{first}/emg-envelope")
    assert gone.status_code == 409 and f"{row.id}.emgc cannot be read" in gone.text
    moved.with_suffix(".away").rename(moved)

    r = client.get(f"/api/trials/{second}/emg-envelope")  # 12 s after the file ends
    assert r.status_code == 409 and f"trial {second} has no EMG" in r.json()["detail"]
    assert client.get("/api/trials/99999/emg-envelope").status_code == 404
    assert client.get(f"/api/trials/{first}/emg-envelope",
                      params={"points": 5}).status_code == 422


def test_a_trial_that_has_not_run_says_so(client: TestClient, db_url: str) -> None:
    made = _session_with_two_trials(db_url)
    engine = make_engine(db_url)
    with Session(engine) as db:
        trial = Trial(session_id=made["session"], controller="pec", task="squat-sequence",
                      planned_order=5, status="planned")
        db.add(trial)
        db.commit()
        tid = trial.id
    engine.dispose()
    r = client.get(f"/api/trials/{tid}/emg-envelope")
    assert r.status_code == 409 and f"trial {tid} has not run" in r.json()["detail"]


def test_a_lift_the_recording_barely_covers_is_not_measured_and_calls_are_bounded(
        client: TestClient, db_url: str, tmp_path: Path) -> None:
    """The attack: a lift measured from a few percent of its samples with no flag. The
    file ends 0.1 s into the 1 s lift: the lift is listed with `no_emg` and its coverage,
    without numbers. Beyond `MAX_CONCURRENT` computations a call gets 503 and
    Retry-After."""
    from backend.emg import trial_envelope

    made = _session_with_two_trials(db_url)
    first = made["trials"][0]
    assert client.put(f"/api/studies/{made['study']}/emg-montage", json=MONTAGE).is_success
    assert client.put(f"/api/trials/{first}/segments", json=[
        {"start": 40, "peak": 90, "end": 140, "label": "squat"}]).is_success
    r = client.post(f"/api/sessions/{made['session']}/emg/edf",
                    files={"file": ("a.edf", _edf(tmp_path, 2.0))},
                    data={"trial": str(first), "offset_s": "-1.5"})
    assert r.status_code == 201, r.text
    r = client.get(f"/api/trials/{first}/emg-envelope")
    assert r.status_code == 200, r.text
    (lift,) = r.json()["lifts"]
    assert lift["peak"] == [] and lift["mean"] == [] and lift["iemg"] == []
    assert lift["flags"] and lift["flags"][0].startswith("no_emg:1")  # ~10 %
    assert isinstance(r.json()["flags"], list)
    held = [trial_envelope.BUSY.acquire(blocking=False)
            for _ in range(trial_envelope.MAX_CONCURRENT)]
    try:
        assert all(held)
        r = client.get(f"/api/trials/{first}/emg-envelope")
        assert r.status_code == 503 and r.headers["retry-after"] == "5"
        assert "try again" in r.json()["detail"]
    finally:
        for _ in held:
            trial_envelope.BUSY.release()
    assert client.get(f"/api/trials/{first}/emg-envelope").status_code == 200


def test_a_trial_whose_emg_is_still_recording_says_so(
        client: TestClient, db_url: str, settings: Any) -> None:
    """The attack: during a live recording the panel answered "subscribe an EMG
    stream" although one was recording."""
    from backend.db.emg import EmgMontage
    from backend.emg import recordings

    made = _session_with_two_trials(db_url)
    first = made["trials"][0]
    assert client.put(f"/api/studies/{made['study']}/emg-montage", json=MONTAGE).is_success
    engine = make_engine(db_url)
    with Session(engine) as db:
        montage = db.query(EmgMontage).filter_by(study_id=made["study"]).one()
        writer = recordings.RecordingWriter(db, settings, made["session"], montage,
                                            "simulated", FS)
        r = client.get(f"/api/trials/{first}/emg-envelope")
        assert r.status_code == 409, r.text
        assert f"recording {writer.row.id}" in r.json()["detail"]
        assert "still recording" in r.json()["detail"]
        assert "subscribe an EMG stream" not in r.json()["detail"]
    engine.dispose()
