"""EDF/BDF headers that cannot describe EMG are a 422 naming the field and its value;
a truncated file is imported with what it holds and a visible flag; an EDF+D file keeps
each record at its own onset; a rate no BDF record holds or beyond float range never
reaches the quality summary's arithmetic (regressions: each was stored, or a 500)."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.emg import recordings, store
from backend.emg.quality_summary import QualitySummary
from tests.backend.emg.test_emg_api import MONTAGE, _edf

LABELS = ["ES-L lumbar", "ES-R lumbar", "GM-L"]
NS = 4  # three channels and the annotation signal


def _ready(client: TestClient) -> str:
    study = client.post("/api/studies", json={"name": "EDF checks"}).json()["id"]
    pid = client.post(f"/api/studies/{study}/participants", json={"code": "P1"}).json()["id"]
    sess = client.post(f"/api/participants/{pid}/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).json()["id"]
    client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    client.post(f"/api/sessions/{sess}/markers", json={"label": "sync"})
    return f"/api/sessions/{sess}/emg/edf"


def _patch(data: bytes, at: int, value: str, width: int = 8) -> bytes:
    return data[:at] + value.ljust(width).encode() + data[at + width:]


def _signal_field(data: bytes, field_at: int, value: str) -> bytes:
    """Set a per-signal field of signal 0 (`field_at`: its offset per signal count)."""
    return _patch(data, 256 + NS * field_at, value)


def _post(client: TestClient, url: str, data: bytes) -> tuple[int, str]:
    r = client.post(url, files={"file": ("a.edf", data)}, data={"marker": "sync"})
    body = r.json()
    msg = body["detail"][0]["msg"] if r.status_code == 422 else str(body)
    return r.status_code, msg


@pytest.mark.parametrize(("field", "value", "words"), [
    (("record", 244), "1e-300", "record duration 1e-300 s"),
    (("signal", 104), "nan", "physical range nan"),
    (("signal", 104), "1000", "physical minimum equals physical maximum (1000.0)"),
    (("signal", 120), "32767", "digital minimum equals digital maximum (32767)"),
])
def test_a_header_that_cannot_be_emg_is_a_422_naming_it(
        client: TestClient, settings: Settings, field: tuple[str, int], value: str,
        words: str) -> None:
    url = _ready(client)
    good, _ = _edf(LABELS, seconds=4)
    kind, at = field
    bad = _patch(good, at, value) if kind == "record" else _signal_field(good, at, value)
    status, msg = _post(client, url, bad)
    assert status == 422 and words in msg, msg
    folder = store.emg_folder(settings)
    assert not folder.exists() or list(folder.iterdir()) == []


def test_a_rate_too_low_for_the_chain_is_a_422_with_the_minimum(client: TestClient) -> None:
    url = _ready(client)
    data, _ = _edf(LABELS, fs=100.0, seconds=4)
    status, msg = _post(client, url, data)
    assert status == 422 and "100.0 Hz is not a surface EMG rate" in msg
    assert f"{recordings.MIN_IMPORT_RATE_HZ:.1f} Hz" in msg and "ES-L lumbar" in msg


def test_a_truncated_file_is_imported_with_a_flag(client: TestClient) -> None:
    url = _ready(client)
    data, _ = _edf(LABELS, seconds=6)
    record = (3 * 2000 + 7) * 2
    r = client.post(url, files={"file": ("a.edf", data[:-record - 100])},
                    data={"marker": "sync"})
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["n_samples"] == 4 * 2000
    assert "file_truncated" in rec["quality"]["flags"]
    assert "holds 4 of the 6 records" in rec["alignment"]


def test_a_discontinuous_file_keeps_each_record_at_its_onset(
        client: TestClient, settings: Settings) -> None:
    url = _ready(client)
    data, truth = _edf(LABELS, seconds=8)
    data = _patch(data, 192, "EDF+D", 44)
    head, rec_len, at = 1280, (3 * 2000 + 7) * 2, 3 * 2000 * 2
    for r in range(5, 8):  # a 10 s pause before record 5
        start = head + r * rec_len + at
        data = data[:start] + f"+{r + 10}\x14\x14\x00".encode().ljust(14, b"\0") \
            + data[start + 14:]
    r = client.post(url, files={"file": ("a.edf", data)}, data={"marker": "sync"})
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["n_samples"] == 8 * 2000
    assert "discontinuous_file" in rec["quality"]["flags"]
    t, x = store.read_window(store.recording_path(settings, rec["id"]))
    assert t[5 * 2000 - 1] == pytest.approx(5.0 - 1 / 2000)
    assert t[5 * 2000] == pytest.approx(15.0)
    assert t[-1] == pytest.approx(18.0 - 1 / 2000)
    np.testing.assert_allclose(x[:, 0], truth[:, 0] * 1e-6, atol=1e-6)


@pytest.mark.parametrize("fs", [1e308, float("inf"), 1.0, 1000.0001])
def test_an_impossible_rate_is_refused_before_any_arithmetic(fs: float) -> None:
    with pytest.raises(ValueError, match="Hz"):
        recordings.check_import_rate(fs) if fs != 1000.0001 else \
            recordings.bids.record_duration(fs)
    if not np.isfinite(fs) or fs > 1e9:
        with pytest.raises(ValueError, match="cannot be assessed"):
            QualitySummary(fs, ["a"])
