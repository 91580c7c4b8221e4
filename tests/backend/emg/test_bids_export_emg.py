"""The study's BIDS export with EMG, end to end: a session whose first trial has a
simulated EMG recording in the store gets an `emg/` folder beside `motion/`, listed in
`_scans.tsv`, and the whole dataset passes the schema-based validator with no error and
no warning (owner and blinded)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from backend.analysis.virtual_study import DATASET_INFO
from backend.core.config import Settings
from backend.db.emg import EmgMontage
from backend.db.engine import make_engine
from backend.db.models import ConditionLabel, Study, StudySession
from backend.emg import recordings, store
from backend.lab.bids_export import dataset_files
from controller.sim.muscles import CHANNELS, channel_label
from controller.sim.surface_emg import SurfaceEmgGenerator
from tests.backend.lab.bids_validator import issues
from tests.backend.lab.test_xdf_import import LSL_MINUS_UNIX, _session_with_two_trials

FS = 2000.0


def _with_emg(db_url: str, settings: Settings) -> dict[str, Any]:
    """The two-trial session, its study described for BIDS, and 4 s of simulated EMG of
    four muscles that cover its first trial (3 s) on the session clock."""
    made = _session_with_two_trials(db_url)
    engine = make_engine(db_url)
    with Session(engine) as db:
        study = db.get(Study, made["study"])
        assert study is not None
        study.dataset_info = DATASET_INFO
        sess_id = int(made["session"])
        sess = db.get(StudySession, sess_id)
        assert sess is not None
        pid = sess.participant_id
        db.add(ConditionLabel(participant_id=pid, controller="pec", label="A"))
        chans = [{"label": channel_label(m, s), "muscle": m, "side": s,
                  "placement": "SENIAM", "electrode_type": "Ag/AgCl",
                  "inter_electrode_distance_mm": 20.0, "reference": "iliac crest"}
                 for m, s in CHANNELS[:4]]
        montage = EmgMontage(study_id=study.id, version=1, placement_scheme="SENIAM",
                             channels=chans)
        db.add(montage)
        db.commit()
        gen = SurfaceEmgGenerator(4, seed=3)
        block = gen.push(np.full((400, 4), 0.3))  # 4 s at 100 Hz ticks -> 8000 samples
        start = made["ticks"][0][0]["t_host"] + LSL_MINUS_UNIX - 0.5
        rec = recordings.store_blocks(db, settings, sess_id, montage, "simulated", FS,
                                      [(None, block.samples)], start, "simulated, test")
        assert [t["trial_id"] for t in rec.trials] == [made["trials"][0]]
        assert rec.trials[0]["complete"]
    engine.dispose()
    return made


@pytest.mark.parametrize("unblind", [True, False], ids=["owner", "blinded"])
def test_a_session_with_emg_exports_valid_bids_emg(
        client: TestClient, db_url: str, settings: Settings, tmp_path: Path,
        unblind: bool) -> None:
    # `client`: the server has created the database's tables.
    made = _with_emg(db_url, settings)
    engine = make_engine(db_url)
    out = tmp_path / "bids"
    with Session(engine) as db:
        for rel, data in dataset_files(engine, db, int(made["study"]),
                                       unblind=unblind, emg_dir=store.emg_folder(settings)):
            path = out / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
    engine.dispose()
    emg = sorted(p.name for p in out.glob("sub-*/ses-*/emg/*"))
    acq = "pec" if unblind else "A"
    stem = f"sub-P01_ses-evaluation1_task-squatsequence_acq-{acq}_run-1"
    assert emg == [f"{stem}_{s}" for s in ("channels.tsv", "emg.bdf", "emg.json",
                                             "events.json", "events.tsv")]
    sidecar = json.loads(next(out.rglob("*_emg.json")).read_text())
    assert sidecar["SamplingFrequency"] == FS and sidecar["PowerLineFrequency"] == 50
    scans = next(out.rglob("*_scans.tsv")).read_text()
    assert f"emg/{stem}_emg.bdf" in scans
    assert issues(out) == []
