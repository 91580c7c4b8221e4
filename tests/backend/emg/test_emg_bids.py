"""BIDS-EMG: a stored recording's trial as BDF with `_emg.json` and `_channels.tsv`
passes the schema-based validator with no error and no warning, and the BDF holds the
stored samples."""

from __future__ import annotations

import io
import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import edfio
import numpy as np
import pytest

from backend.emg import bids, store
from backend.lab.bids_export import _json, _tsv
from tests.backend.lab.bids_validator import issues

CHANNELS = [{"label": "ES-L", "muscle": "erector_spinae_lumbar", "side": "left",
             "placement": "SENIAM longissimus", "electrode_type": "Ag/AgCl",
             "inter_electrode_distance_mm": 20.0, "reference": ""},
            {"label": "GM-R", "muscle": "gluteus_maximus", "side": "right",
             "placement": "", "electrode_type": "", "inter_electrode_distance_mm": None,
             "reference": ""}]


def _recording(folder: Path) -> tuple[Any, np.ndarray]:
    fs = 2000.0
    t = np.arange(int(6 * fs)) / fs
    x = np.random.default_rng(2).normal(0, 1e-4, (t.size, 2))
    x[100, 1] = np.nan
    w = store.EmgWriter(folder / "1.emgc", ["ES-L", "GM-R"], fs)
    w.append(t, x)
    w.close()
    rec = SimpleNamespace(id=1, fs=fs, t_start=100.0, t_end=100.0 + t[-1], time_offset_s=100.0,
                          source="edf", status="complete", quality={},
                          trials=[{"trial_id": 7, "start": 101.0, "stop": 105.0,
                                   "complete": True}])
    return rec, x


def test_an_interrupted_recording_and_a_cut_trial_say_so_in_the_sidecar(
        tmp_path: Path) -> None:
    """A recording a killed server left covers the trial's first 2.0 of 4.5 s: the
    file holds what there is, and its description says what it is not."""
    rec, _x = _recording(tmp_path)
    rec.status, rec.quality = "interrupted", {"flags": ["interrupted"]}
    rec.trials = [{"trial_id": 7, "start": 104.0, "stop": 108.5, "complete": False}]
    montage = SimpleNamespace(channels=CHANNELS, placement_scheme="")
    parts = dict(bids.trial_files(tmp_path, rec, montage, 7, "s", "squat",  # type: ignore[arg-type]
                                  "squats", 50, {}))
    text = parts["s_emg.json"]["TaskDescription"]
    assert text.startswith("squats. The recording was interrupted (its server stopped)")
    assert "This file holds 2.00 s of the trial's 4.50 s" in text
    assert parts["s_emg.json"]["RecordingDuration"] == pytest.approx(2.0, abs=1e-3)


@pytest.mark.slow
def test_a_trials_emg_validates_with_no_error_and_no_warning(tmp_path: Path) -> None:
    rec, x = _recording(tmp_path)
    montage = SimpleNamespace(channels=CHANNELS, placement_scheme="SENIAM 8 where available")
    stem = "sub-P01_ses-evaluation1_task-squat_acq-A_run-1"
    parts = dict(bids.trial_files(tmp_path, rec, montage, 7, stem, "squat",  # type: ignore[arg-type]
                                  "squats", 50, {"highpass_hz": 20.0}))
    root = tmp_path / "ds"
    emg = root / "sub-P01" / "ses-evaluation1" / "emg"
    emg.mkdir(parents=True)
    (root / "dataset_description.json").write_text(_json(
        {"Name": "t", "BIDSVersion": "1.11.0", "DatasetType": "raw", "HEDVersion": "8.3.0",
         "Authors": ["A", "B"], "License": "CC0",
         "GeneratedBy": [{"Name": "ExoStudy"}],
         "SourceDatasets": [{"URL": "bids::sourcedata/"}]}))
    (root / "README").write_text("EMG test dataset: one trial of surface EMG of two "
                                 "muscles, written by the BIDS-EMG export of ExoStudy.\n" * 3)
    (root / "participants.tsv").write_text("participant_id\nsub-P01\n")
    (root / "participants.json").write_text(_json(
        {"participant_id": {"Description": "code"}}))
    (emg / f"{stem}_emg.bdf").write_bytes(parts[f"{stem}_emg.bdf"])
    (emg / f"{stem}_emg.json").write_text(_json(parts[f"{stem}_emg.json"]))
    cols, rows = parts[f"{stem}_channels.tsv"]
    (emg / f"{stem}_channels.tsv").write_text(_tsv(cols, rows))
    (emg / f"{stem}_events.tsv").write_text(_tsv(["onset", "duration", "trial_type"],
                                                 [[0.5, 1.0, "lift"]]))
    (emg / f"{stem}_events.json").write_text(_json({
        "trial_type": {"Description": "kind", "Levels": {"lift": "a lift"}},
        "StimulusPresentation": {"SoftwareName": "ExoStudy"}}))
    assert issues(root) == []

    assert parts["shift"] == pytest.approx(101.0)
    bdf = edfio.read_bdf(io.BytesIO(parts[f"{stem}_emg.bdf"]))
    got = np.column_stack([s.data for s in bdf.signals]) * 1e-6
    want = x[2000:10001]
    want = np.where(np.isfinite(want), want, 0.0)
    step = 2 * np.abs(want).max() * 1.01 / 2**24
    np.testing.assert_allclose(got[: want.shape[0]], want[: got.shape[0]], atol=2 * step)
    assert rows[1][7] == "good" and rows[0][7] == "good"
    assert json.loads(_json(parts[f"{stem}_emg.json"]))["PowerLineFrequency"] == 50
