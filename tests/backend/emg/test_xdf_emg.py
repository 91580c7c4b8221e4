"""EMG from a LabRecorder XDF file: the amplifier's stream, recorded on a third clock
beside ExoStudy's tick stream on another host, lands in the EMG store on the session
clock (the file's clock offsets, then the tick stream), mapped by the montage; bad
streams are refused with what is wrong (nothing stored), doubtful ones flagged."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.emg import store
from tests.backend.lab.test_xdf_import import (
    FILE_SHIFT,
    LSL_MINUS_UNIX,
    _session_with_two_trials,
    _xdf,
)
from tests.backend.lab.xdf_writer import XdfStream, write_xdf

FS = 2000.0
#: The amplifier's clock minus the LabRecorder computer's, as its clock offsets say.
AMP_BEHIND = 2.5
MONTAGE: dict[str, Any] = {"placement_scheme": "SENIAM", "channels": [
    {"label": "GM-L", "muscle": "gluteus_maximus", "side": "left"},
    {"label": "ES-L lumbar", "muscle": "erector_spinae_lumbar", "side": "left"},
    {"label": "ES-R lumbar", "muscle": "erector_spinae_lumbar", "side": "right"},
]}
LABELS = ["es_l_LUMBAR", "ES.R lumbar", "gm l", "spare"]


def _emg(t0: float, n: int = 4000, units: str = "uV", period: float = 1 / FS,
         fmt: str = "float32", labels: list[str] | None = None,
         bad: bool = False) -> tuple[XdfStream, np.ndarray]:
    """`n` samples from file time `t0` (LabRecorder's clock) on the amplifier's clock."""
    rng = np.random.default_rng(5)
    rows = rng.normal(0, 100.0, (n, 4)).astype(np.float32)  # microvolts
    if bad:
        rows[100, 1] = np.nan
        rows[200, 0] = np.inf
    stamps = [t0 - AMP_BEHIND + i * period for i in range(n)]
    offsets = [(stamps[0], AMP_BEHIND), (stamps[-1], AMP_BEHIND)]
    return XdfStream("Amplifier", "EMG", labels or LABELS, FS, fmt, stamps, rows.tolist(),
                     clock_offsets=offsets, units=[units] * 4), rows


def _setup(client: TestClient, db_url: str) -> dict[str, Any]:
    made = _session_with_two_trials(db_url)
    r = client.put(f"/api/studies/{made['study']}/emg-montage", json=MONTAGE)
    assert r.status_code == 200, r.text
    return made


def _file(made: dict[str, Any], emg: XdfStream | None) -> bytes:
    _, streams = _xdf(made["ticks"][0])
    return write_xdf(streams + ([emg] if emg is not None else []))


def _post(client: TestClient, sess: int, data: bytes, **form: str) -> Any:
    return client.post(f"/api/sessions/{sess}/emg/xdf", data={"ignore_labels": "spare", **form},
                       files={"file": ("lab.xdf", data, "application/octet-stream")})


def test_the_emg_stream_of_an_xdf_is_stored_on_the_session_clock(
        client: TestClient, db_url: str, settings: Settings) -> None:
    made = _setup(client, db_url)
    sess = made["session"]
    start = made["ticks"][0][0]["t_host"] + LSL_MINUS_UNIX  # trial 1's start, our clock
    emg, rows = _emg(start + FILE_SHIFT + 0.5)
    r = _post(client, sess, _file(made, emg))
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["source"] == "xdf" and rec["fs"] == FS and rec["n_samples"] == 4000
    assert rec["labels"] == ["GM-L", "ES-L lumbar", "ES-R lumbar"]
    assert rec["time_offset_s"] == pytest.approx(-FILE_SHIFT, abs=1e-6)
    assert rec["t_start"] == pytest.approx(start + 0.5, abs=1e-6)
    assert "tick stream" in rec["alignment"]
    assert [t["trial_id"] for t in rec["trials"]] == [made["trials"][0]]
    assert rec["quality"]["flags"] == []
    t, x = store.read_window(store.recording_path(settings, rec["id"]))
    np.testing.assert_allclose(t + rec["time_offset_s"], start + 0.5 + np.arange(4000) / FS,
                               atol=1e-6)
    np.testing.assert_allclose(x, rows[:, [2, 0, 1]].astype(np.float64) * 1e-6, rtol=1e-6)


def test_bad_emg_streams_are_refused_or_flagged(
        client: TestClient, db_url: str) -> None:
    made = _setup(client, db_url)
    sess = made["session"]
    t0 = made["ticks"][0][0]["t_host"] + LSL_MINUS_UNIX + FILE_SHIFT
    recs = f"/api/sessions/{sess}/emg-recordings"

    def refused(data: bytes, *words: str, **form: str) -> dict[str, Any]:
        r = _post(client, sess, data, **form)
        assert r.status_code == 422, r.text
        detail = r.json()["detail"][0]
        assert detail["loc"] == ["body", "file"]
        for w in words:
            assert w in detail["msg"], detail["msg"]
        return dict(detail)

    refused(_file(made, None), "no stream of type EMG", "'Mocap'")
    refused(_file(made, _emg(t0, units="N")[0]), "'N' is not a voltage", "'gm l'")
    detail = refused(_file(made, _emg(t0, labels=["a", "ES.R lumbar", "gm l", "spare"])[0]),
                     "match no entry")
    assert detail["unmatched_labels"] == ["a"] and detail["missing_labels"] == ["ES-L lumbar"]
    refused(_file(made, _emg(t0)[0]), "no stream 'EEG'", stream="EEG")
    refused(_file(made, _emg(t0)[0]), "not of type EMG", stream="Mocap")
    refused(b"XDF:" + b"\x00" * 10, "")
    assert client.get(recs).json() == []  # nothing stored

    # Stored, and flagged: non-finite samples, and stamps that disagree with the rate.
    r = _post(client, sess, _file(made, _emg(t0, bad=True)[0]), stream="Amplifier")
    assert r.status_code == 201, r.text
    q = r.json()["quality"]
    assert q["non_finite_samples"] == 2 and "non_finite" in q["flags"]
    r = _post(client, sess, _file(made, _emg(t0, period=1 / 1900)[0]))
    assert r.status_code == 201, r.text
    q = r.json()["quality"]
    assert "rate_mismatch" in q["flags"] and q["rate_from_timestamps_hz"] == pytest.approx(
        1900, rel=1e-6)
    # Without ExoStudy's tick stream the alignment is an assumption, and says so.
    emg, _ = _emg(t0)
    r = _post(client, sess, write_xdf([emg]))
    assert r.status_code == 201, r.text
    assert "alignment_assumed" in r.json()["quality"]["flags"]
    assert len(client.get(recs).json()) == 3
