"""Muscle activity through the API: montage versions with validation, the study's EMG
analysis settings, EDF/BDF imports aligned through the session's markers (and every bad
file refused with nothing stored), and MVC steps timed with markers."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import edfio
import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.emg import store

MONTAGE: dict[str, Any] = {"placement_scheme": "SENIAM", "channels": [
    {"label": "ES-L lumbar", "muscle": "erector_spinae_lumbar", "side": "left",
     "placement": "SENIAM longissimus", "electrode_type": "Ag/AgCl",
     "inter_electrode_distance_mm": 20, "reference": "iliac crest"},
    {"label": "ES-R lumbar", "muscle": "erector_spinae_lumbar", "side": "right"},
    {"label": "GM-L", "muscle": "gluteus_maximus", "side": "left"},
]}


def _session(client: TestClient) -> tuple[int, int]:
    study = client.post("/api/studies", json={"name": "EMG"}).json()["id"]
    pid = client.post(f"/api/studies/{study}/participants", json={"code": "P1"}).json()["id"]
    sess = client.post(f"/api/participants/{pid}/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).json()["id"]
    return int(study), int(sess)


def _edf(labels: list[str], fs: float = 2000.0, seconds: int = 12, unit: str = "uV",
         sync_at: float | None = 2.0, bdf: bool = False) -> tuple[bytes, np.ndarray]:
    rng = np.random.default_rng(1)
    data = rng.normal(0, 50.0, (int(fs * seconds), len(labels)))  # microvolts
    data[:, -1] = np.sin(np.arange(data.shape[0]) / fs * 2 * np.pi * 80) * 100
    cls: Any = edfio.Bdf if bdf else edfio.Edf
    sig: Any = edfio.BdfSignal if bdf else edfio.EdfSignal
    kw: dict[str, Any] = {"physical_range": (-1000.0, 1000.0)}
    if bdf:
        kw["digital_range"] = (-8388608, 8388607)
    signals = [sig(data[:, i], fs, label=lb, physical_dimension=unit, **kw)
               for i, lb in enumerate(labels)]
    ann = [edfio.EdfAnnotation(sync_at, None, "sync")] if sync_at is not None else []
    edf = cls(signals, annotations=ann)
    path = Path(f"/tmp/emg-test-{id(edf)}.{'bdf' if bdf else 'edf'}")
    edf.write(path)
    out = path.read_bytes()
    path.unlink()
    return out, data


def test_montage_versions_and_validation(client: TestClient) -> None:
    study, _ = _session(client)
    url = f"/api/studies/{study}/emg-montage"
    assert client.get(url).status_code == 404
    r = client.put(url, json=MONTAGE)
    assert r.status_code == 200, r.text
    assert r.json()["version"] == 1 and r.json()["channels"][0]["inter_electrode_distance_mm"] == 20
    second = {**MONTAGE, "channels": MONTAGE["channels"][:2]}
    assert client.put(url, json=second).json()["version"] == 2
    assert [m["version"] for m in client.get(f"/api/studies/{study}/emg-montages").json()] \
        == [1, 2]
    assert len(client.get(url).json()["channels"]) == 2

    bad = {"channels": [{"label": "x", "muscle": "biceps", "side": "left"}]}
    r = client.put(url, json=bad)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "channels", 0, "muscle"]
    dup = {"channels": [MONTAGE["channels"][0], {**MONTAGE["channels"][1], "label": "es_l LUMBAR"}]}
    r = client.put(url, json=dup)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "channels", 1, "label"]
    assert "duplicate channel" in r.json()["detail"][0]["msg"]
    twice = {"channels": [MONTAGE["channels"][0], {**MONTAGE["channels"][0], "label": "other"}]}
    r = client.put(url, json=twice)
    assert r.json()["detail"][0]["loc"] == ["body", "channels", 1, "muscle"]
    assert client.get(url).json()["version"] == 2  # nothing stored by the refusals
    assert client.delete(url).status_code == 200
    assert client.get(url).status_code == 404


def test_emg_settings_store_every_parameter_and_the_normalisation(client: TestClient) -> None:
    study, _ = _session(client)
    url = f"/api/studies/{study}/emg-settings"
    default = client.get(url).json()
    assert default["normalisation"] == "mvc" and default["processing"]["highpass_hz"] == 20.0
    r = client.put(url, json={"processing": {"highpass_hz": 30.0, "notch_hz": 50},
                              "normalisation": "task_peak", "mains_hz": 50})
    assert r.status_code == 200, r.text
    got = client.get(url).json()
    assert got["normalisation"] == "task_peak" and got["processing"]["highpass_hz"] == 30.0
    assert got["processing"]["envelope_hz"] == 6.0 and got["processing"]["version"] == 1
    r = client.put(url, json={"processing": {"highpass_hz": 500.0}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "processing"]
    for bad, field in (({"notch_hz": 50, "notch_q": 1e-300}, "notch_q"),
                       ({"envelope_hz": 5000}, "envelope_hz"),
                       ({"highpass_hz": 1e307}, "highpass_hz"),
                       ({"highpass_hz": True}, "highpass_hz"),
                       ({"remove_dc": "no"}, "remove_dc")):
        r = client.put(url, json={"processing": bad})
        assert r.status_code == 422, (bad, r.text)
        assert field in r.json()["detail"][0]["msg"]
    r = client.put(url, json={"processing": {"bogus": 1}})
    assert r.status_code == 422 and "bogus" in r.json()["detail"][0]["msg"]
    r = client.put(url, json={"normalisation": "peak"})
    assert r.status_code == 422
    assert client.get(url).json()["normalisation"] == "task_peak"


@pytest.mark.parametrize("bdf", [False, True], ids=["edf", "bdf"])
def test_edf_import_aligned_by_a_marker(client: TestClient, settings: Settings,
                                        bdf: bool) -> None:
    study, sess = _session(client)
    client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    marker = client.post(f"/api/sessions/{sess}/markers", json={"label": "sync"}).json()
    data, truth = _edf(["GM-L", "ES-R lumbar", "spare 1", "ES-L lumbar"], bdf=bdf)
    r = client.post(f"/api/sessions/{sess}/emg/edf", files={"file": ("a.bdf", data)},
                    data={"marker": "sync", "ignore_labels": "spare 1"})
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["source"] == ("bdf" if bdf else "edf") and rec["fs"] == 2000.0
    assert rec["labels"] == ["ES-L lumbar", "ES-R lumbar", "GM-L"]
    assert rec["n_samples"] == truth.shape[0] and rec["montage_version"] == 1
    assert rec["time_offset_s"] == pytest.approx(marker["lsl_time"] - 2.0)
    path = store.recording_path(settings, rec["id"])
    assert store.file_sha256(path) == rec["sha256"]
    t, x = store.read_window(path)
    assert t[0] == 0.0 and t[1] == pytest.approx(1 / 2000.0)
    # Montage order, volts, within the file's quantisation step.
    step = 2000.0 / (2**24 if bdf else 2**16) * 1e-6
    np.testing.assert_allclose(x[:, 0], truth[:, 3] * 1e-6, atol=step)
    np.testing.assert_allclose(x[:, 2], truth[:, 0] * 1e-6, atol=step)
    assert "sync" in rec["alignment"]
    listed = client.get(f"/api/sessions/{sess}/emg-recordings").json()
    assert [x["id"] for x in listed] == [rec["id"]]


def test_bad_files_are_refused_and_nothing_is_stored(client: TestClient,
                                                     settings: Settings) -> None:
    study, sess = _session(client)
    url = f"/api/sessions/{sess}/emg/edf"
    good, _ = _edf(["ES-L lumbar", "ES-R lumbar", "GM-L"])
    r = client.post(url, files={"file": ("a.edf", good)}, data={"marker": "sync"})
    assert r.status_code == 409 and "no EMG montage" in r.json()["detail"]
    client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    client.post(f"/api/sessions/{sess}/markers", json={"label": "sync"})

    data, _ = _edf(["ES-L lumbar", "ES-R lumbar", "GM-L", "TA-R"])
    r = client.post(url, files={"file": ("a.edf", data)}, data={"marker": "sync"})
    assert r.status_code == 422
    d = r.json()["detail"][0]
    assert d["unmatched_labels"] == ["TA-R"]
    assert d["expected_labels"] == ["ES-L lumbar", "ES-R lumbar", "GM-L"]
    assert "TA-R" in d["msg"] and "ES-L lumbar" in d["msg"]

    data, _ = _edf(["ES-L lumbar", "ES-R lumbar", "GM-L"], unit="degC")
    r = client.post(url, files={"file": ("a.edf", data)}, data={"marker": "sync"})
    assert r.status_code == 422 and "not a voltage" in r.json()["detail"][0]["msg"]
    r = client.post(url, files={"file": ("a.edf", good)}, data={"marker": "nope"})
    assert r.status_code == 422 and "no annotation 'nope'" in r.json()["detail"][0]["msg"]
    r = client.post(url, files={"file": ("a.edf", good)})
    assert r.status_code == 422 and "say how to align" in r.json()["detail"][0]["msg"]
    r = client.post(url, files={"file": ("a.edf", b"0       garbage")}, data={"marker": "sync"})
    assert r.status_code == 422 and "not a readable EDF" in r.json()["detail"][0]["msg"]
    r = client.post(url, files={"file": ("a.edf", good)}, data={"trial": 5})
    assert r.status_code == 422 and "trial 5" in r.json()["detail"][0]["msg"]

    assert client.get(f"/api/sessions/{sess}/emg-recordings").json() == []
    folder = store.emg_folder(settings)
    assert not folder.exists() or list(folder.iterdir()) == []


def test_quality_flags_of_an_import_are_kept_and_shown(client: TestClient) -> None:
    study, sess = _session(client)
    client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    client.post(f"/api/sessions/{sess}/markers", json={"label": "sync"})
    labels = ["ES-L lumbar", "ES-R lumbar", "GM-L"]
    rng = np.random.default_rng(3)
    n = 24_000
    data = rng.normal(0, 50.0, (n, 3))
    data[:, 1] = 0.0  # electrode off
    data[:, 2] = np.clip(data[:, 2] * 30, -1000, 1000)  # at the rails
    sigs = [edfio.EdfSignal(data[:, i], 2000.0, label=lb, physical_dimension="uV",
                            physical_range=(-1000.0, 1000.0)) for i, lb in enumerate(labels)]
    path = Path(f"/tmp/emg-q-{id(sigs)}.edf")
    edfio.Edf(sigs, annotations=[edfio.EdfAnnotation(0.0, None, "sync")]).write(path)
    raw = path.read_bytes()
    path.unlink()
    r = client.post(f"/api/sessions/{sess}/emg/edf", files={"file": ("q.edf", raw)},
                    data={"marker": "sync"})
    assert r.status_code == 201, r.text
    q = r.json()["quality"]
    assert "flat_line" in q["channels"]["ES-R lumbar"]
    assert "clipping" in q["channels"]["GM-L"]
    assert "flat_line" not in q["channels"].get("ES-L lumbar", {})
    assert {"flat_line", "clipping"} <= set(q["flags"])
    assert r.json()["n_samples"] == n  # flagged, not dropped


def test_mvc_steps_are_timed_with_markers(client: TestClient) -> None:
    study, sess = _session(client)
    url = f"/api/sessions/{sess}/mvc-steps"
    r = client.put(url, json={"steps": [{"muscle": "erector_spinae_lumbar"}]})
    assert r.status_code == 409 and "no EMG montage" in r.text  # nothing to record with
    assert client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE).status_code == 200
    r = client.put(url, json={"steps": [
        {"muscle": "erector_spinae_lumbar", "repetitions": 2},
        {"muscle": "gluteus_maximus", "side": "left", "repetitions": 1}]})
    assert r.status_code == 200, r.text
    steps = r.json()
    assert [s["planned_order"] for s in steps] == [0, 1]
    r = client.put(url, json={"steps": [{"muscle": "quadriceps"}]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == "muscle"
    ev = f"{url}/{steps[0]['id']}/events"
    r = client.post(ev, json={"event": "stop"})
    assert r.status_code == 409 and "no repetition is running" in r.json()["detail"]
    assert client.post(ev, json={"event": "start"}).status_code == 200
    assert client.post(ev, json={"event": "start"}).status_code == 409
    done = client.post(ev, json={"event": "stop"}).json()["repetitions_done"]
    assert done[0]["rep"] == 1 and done[0]["stop_marker_id"] > done[0]["start_marker_id"]
    client.post(ev, json={"event": "start"})
    client.post(ev, json={"event": "stop"})
    r = client.post(ev, json={"event": "start"})
    assert r.status_code == 409 and "all 2 repetitions" in r.json()["detail"]
    marks = client.get(f"/api/sessions/{sess}/markers").json()
    assert [(m["label"], m["note"]) for m in marks] == [
        ("mvc_start", "erector_spinae_lumbar both rep 1"),
        ("mvc_stop", "erector_spinae_lumbar both rep 1"),
        ("mvc_start", "erector_spinae_lumbar both rep 2"),
        ("mvc_stop", "erector_spinae_lumbar both rep 2")]
    r = client.put(url, json={"steps": [{"muscle": "gluteus_maximus", "side": "left"}]})
    assert r.status_code == 409  # a repetition ran: the plan is data now


def test_mvc_plans_fit_the_montage_and_concurrent_starts_store_one_marker(
        client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    """The attack: six concurrent starts gave four 200s and duplicate markers; plans
    with muscles the montage lacks, or a step twice, were stored."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from backend.lab.hub import Lab

    study, sess = _session(client)
    assert client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE).status_code == 200
    url = f"/api/sessions/{sess}/mvc-steps"
    for steps, where in (([{"muscle": "gluteus_maximus"}], 0),  # right side not recorded
                         ([{"muscle": "biceps_femoris", "side": "left"}], 0),
                         ([{"muscle": "erector_spinae_lumbar"},
                           {"muscle": "erector_spinae_lumbar", "side": "left"}], 1)):
        r = client.put(url, json={"steps": steps})
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "steps", where, "muscle"]
    assert client.get(url).json() == []
    r = client.put(url, json={"steps": [{"muscle": "erector_spinae_lumbar"}]})
    assert r.status_code == 200, r.text
    ev = f"{url}/{r.json()[0]['id']}/events"
    gate = threading.Barrier(3)
    real = Lab.console_marker

    def together(self: Lab, *args: object, **kw: object) -> object:
        try:  # every start has read the step before one stores its marker
            gate.wait(2.0)
        except threading.BrokenBarrierError:
            pass
        return real(self, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(Lab, "console_marker", together)
    with ThreadPoolExecutor(3) as pool:
        codes = sorted(x.status_code for x in pool.map(
            lambda _: client.post(ev, json={"event": "start"}), range(3)))
    assert codes == [200, 409, 409]
    marks = client.get(f"/api/sessions/{sess}/markers").json()
    assert [m["label"] for m in marks] == ["mvc_start"]
