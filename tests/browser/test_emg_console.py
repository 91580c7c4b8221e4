"""Muscle activity in the console, in a real browser: the live page's EMG strip shows the
envelope of an amplifier's LSL stream with its flags, a trial's results panel shows the
stored EMG over the trial with its lifts, and the session page's MVC buttons time the
repetitions and store their markers."""

from __future__ import annotations

import os
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

os.environ.setdefault("LSLAPICFG", str(Path(__file__).parents[1] / "backend" / "lab"
                                       / "lsl_api.cfg"))

import httpx
import numpy as np
import pylsl
import pytest

from backend.core.config import Settings
from tests.browser.login_page import log_in_through
from tests.live_server import running_server
from tests.polling import wait_for

FS = 2000.0
CHUNK = 20
LABELS = ["ES-L", "ES-R", "GM-L", "GM-R"]
MONTAGE = {"placement_scheme": "SENIAM", "channels": [
    {"label": "ES-L", "muscle": "erector_spinae_lumbar", "side": "left"},
    {"label": "ES-R", "muscle": "erector_spinae_lumbar", "side": "right"},
    {"label": "GM-L", "muscle": "gluteus_maximus", "side": "left"},
    {"label": "GM-R", "muscle": "gluteus_maximus", "side": "right"},
]}
#: ES-L: a 100 Hz sine of this amplitude. The band-pass passes 100 Hz unchanged (gain
#: 1 within 0.1 %), the rectified sine's mean is 2 A / pi, and the 6 Hz envelope leaves
#: its 200 Hz ripple below 1e-6 of it: the strip settles at 127.3 uV.
AMPLITUDE_V = 200e-6
SETTLED_UV = 2 * AMPLITUDE_V / np.pi * 1e6
NAN_SAMPLES = 10


@pytest.fixture(scope="module")
def shared_server(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path]
                  ) -> Iterator[tuple[str, str, dict[str, str]]]:
    """One server (real worker, simulated exoskeleton) on one database for this module:
    (URL, database URL, the experimenter's login). Each test makes its own study and
    session, so none needs a fresh database, and a server with its worker process
    started per test was most of this module's CPU."""
    from tests.databases import fresh_database
    from tests.login import create_experimenter

    models, folder = default_sets
    with fresh_database(tmp_path_factory.mktemp("emg-console")) as url:
        login = create_experimenter(url)
        settings = Settings(  # type: ignore[call-arg]
            database_url=url, start_worker=True, models_path=models, utilities_dir=folder,
            device_kind="sim", demo=False, _env_file=None)
        with running_server(settings) as base:
            yield base, url, login


@pytest.fixture
def server(shared_server: tuple[str, str, dict[str, str]]) -> str:
    return shared_server[0]


@pytest.fixture
def db_url(shared_server: tuple[str, str, dict[str, str]]) -> str:
    return shared_server[1]


@pytest.fixture
def experimenter(shared_server: tuple[str, str, dict[str, str]]) -> dict[str, str]:
    return shared_server[2]


def _ok(r: httpx.Response) -> Any:
    assert r.is_success, r.text
    return r.json()


def _until(page: Any, expression: str, timeout: float) -> Any:
    return wait_for(lambda: page.evaluate(expression), timeout, expression, poll=0.1)


def _api(server: str, experimenter: dict[str, str]) -> httpx.Client:
    api = httpx.Client(base_url=server, timeout=30)
    token = _ok(api.post("/api/auth/token", json=experimenter))["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    return api


def _session(api: httpx.Client, name: str) -> tuple[int, int]:
    study = _ok(api.post("/api/studies", json={"name": name}))["id"]
    _ok(api.put(f"/api/studies/{study}/emg-montage", json=MONTAGE))
    pid = _ok(api.post(f"/api/studies/{study}/participants", json={"code": "P01"}))["id"]
    sess = _ok(api.post(f"/api/participants/{pid}/sessions",
                        json={"kind": "evaluation", "precompression_pct": 25}))["id"]
    return int(study), int(sess)


class Amplifier:
    """Four channels at 2 kHz on LSL, pushed in 10 ms chunks: ES-L a steady sine, ES-R
    flat (electrode off), GM-L a square wave at the amplifier's rails (clipping), GM-R
    noise that carries `NAN_SAMPLES` NaN samples once `inject` is set."""

    def __init__(self) -> None:
        self.source = f"browser-emg-{uuid.uuid4().hex[:8]}"
        info = pylsl.StreamInfo("BrowserEMG", "EMG", 4, FS, pylsl.cf_float32, self.source)
        chans = info.desc().append_child("channels")
        for label in LABELS:
            ch = chans.append_child("channel")
            ch.append_child_value("label", label)
            ch.append_child_value("unit", "V")
        self.outlet = pylsl.StreamOutlet(info, chunk_size=CHUNK)
        self.inject = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._rng = np.random.default_rng(7)

    def _block(self, n0: int) -> np.ndarray:
        t = (n0 + np.arange(CHUNK)) / FS
        x = np.zeros((CHUNK, 4), dtype=np.float32)
        x[:, 0] = AMPLITUDE_V * np.sin(2 * np.pi * 100.0 * t)
        x[:, 2] = np.where(np.sin(2 * np.pi * 50.0 * t + 0.1) >= 0, 1e-3, -1e-3)
        x[:, 3] = self._rng.normal(0.0, 50e-6, CHUNK)
        return x

    def _run(self) -> None:
        n = 0
        injected = False
        start = time.monotonic()
        while not self._stop.is_set():
            x = self._block(n)
            if self.inject.is_set() and not injected:
                x[:NAN_SAMPLES, 3] = np.nan
                injected = True
            self.outlet.push_chunk(x, pylsl.local_clock())
            n += CHUNK
            self._stop.wait(max(0.0, start + n / FS - time.monotonic()))

    def __enter__(self) -> Amplifier:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        del self.outlet


@pytest.fixture
def amplifier() -> Iterator[Amplifier]:
    with Amplifier() as amp:
        yield amp


def test_the_live_strip_shows_each_channels_envelope_and_flags(
        page: Any, server: str, experimenter: dict[str, str], amplifier: Amplifier) -> None:
    api = _api(server, experimenter)
    _, sess = _session(api, "EMG strip")
    sub = _ok(api.post(f"/api/sessions/{sess}/emg-streams", json={
        "name": "BrowserEMG", "source_id": amplifier.source}))
    log_in_through(page, server, "/live", experimenter)
    _until(page, "window.exostudyLive.emg && window.exostudyLive.emg.values > 100", 30)
    assert page.is_visible("#emg-strip")
    rows = page.locator(f"#emg-strip [data-subscription='{sub['id']}'] .emg-row")
    assert rows.count() == 4
    # The flags of the last 0.5 s, then the NaN samples counted once injected.
    _until(page, "document.querySelector(\"[data-channel='GM-L']\").dataset.clipping"
           " === 'true'", 10)
    amplifier.inject.set()
    _until(page, f"window.exostudyLive.emg.flags['GM-R'].non_finite === {NAN_SAMPLES}", 10)
    # More than 2 s of stream by now: the sine's envelope has settled (the 6 Hz
    # low-pass's time constant is tens of ms).
    es_l = page.locator("#emg-strip [data-channel='ES-L']")
    shown = float(es_l.locator(".emg-value").get_attribute("data-value"))
    assert shown == pytest.approx(SETTLED_UV, rel=0.02)
    assert es_l.locator(".emg-value").inner_text() == f"{shown:.0f} µV"
    assert es_l.get_attribute("data-flat") == "false"
    assert es_l.get_attribute("data-clipping") == "false"
    assert es_l.locator(".emg-flags").inner_text() == ""
    es_r = page.locator("#emg-strip [data-channel='ES-R']")
    assert es_r.get_attribute("data-flat") == "true"
    assert es_r.locator(".emg-flags").inner_text() == "FLAT"
    assert float(es_r.locator(".emg-value").get_attribute("data-value")) == pytest.approx(
        0.0, abs=1e-6)
    gm_l = page.locator("#emg-strip [data-channel='GM-L']")
    assert gm_l.locator(".emg-flags").inner_text() == "CLIPPING"
    gm_r = page.locator("#emg-strip [data-channel='GM-R']")
    assert gm_r.locator(".emg-flags").inner_text() == f"NaN {NAN_SAMPLES}"
    assert gm_r.get_attribute("data-non-finite") == str(NAN_SAMPLES)
    _ok(api.delete(f"/api/sessions/{sess}/emg-streams/{sub['id']}"))


# ------------------------------------------------------------------ the trial's EMG panel
#: The trial's two lifts, as tick indices (100 per second from the trial's first tick).
LIFTS = [(50, 150), (180, 280)]
#: ES-L's sine amplitude: a smooth bump to PEAK_UV over the first lift (no step, so the
#: zero-phase envelope has no overshoot), BASE_UV elsewhere; the envelope's peak over a
#: lift is then 2 A / pi of the largest amplitude in it.
BASE_V = 50e-6
BUMP_V = 200e-6


def _edf_bytes(seconds: float, lead_s: float) -> bytes:
    import edfio

    n = int(seconds * FS)
    t = np.arange(n) / FS - lead_s  # seconds from the trial's start
    a0, a1 = LIFTS[0][0] / 100, LIFTS[0][1] / 100
    bump = np.where((t >= a0) & (t <= a1), np.sin(np.pi * (t - a0) / (a1 - a0)) ** 2, 0.0)
    amp = BASE_V + (BUMP_V - BASE_V) * bump
    rng = np.random.default_rng(4)
    data = np.column_stack([amp * np.sin(2 * np.pi * 100.0 * t),
                            rng.normal(0, 20e-6, n), rng.normal(0, 20e-6, n),
                            rng.normal(0, 20e-6, n)]) * 1e6  # microvolts
    signals = [edfio.EdfSignal(data[:, i], FS, label=lb, physical_dimension="uV",
                               physical_range=(-1000.0, 1000.0))
               for i, lb in enumerate(LABELS)]
    path = Path(f"/tmp/emg-panel-{uuid.uuid4().hex}.edf")
    edfio.Edf(signals).write(path)
    try:
        return path.read_bytes()
    finally:
        path.unlink()


def test_the_trial_panel_shows_the_stored_envelope_with_its_lifts(
        page: Any, server: str, db_url: str, experimenter: dict[str, str]) -> None:
    from tests.backend.lab.test_xdf_import import _session_with_two_trials

    made = _session_with_two_trials(db_url)
    api = _api(server, experimenter)
    study, sess = made["study"], made["session"]
    with_emg, without = made["trials"]
    _ok(api.put(f"/api/studies/{study}/emg-montage", json=MONTAGE))
    _ok(api.put(f"/api/trials/{with_emg}/segments", json=[
        {"start": a, "peak": (a + b) // 2, "end": b, "label": "squat"} for a, b in LIFTS]))
    lead = 1.0
    _ok(api.post(f"/api/sessions/{sess}/emg/edf",
                 files={"file": ("amp.edf", _edf_bytes(5.0, lead))},
                 data={"trial": str(with_emg), "offset_s": str(-lead)}))
    r = api.get(f"/api/trials/{without}/emg-envelope")
    assert r.status_code == 409 and "has no EMG" in r.json()["detail"], r.text

    log_in_through(page, server, f"/console/studies/{study}/results", experimenter)
    page.wait_for_function("window.exostudyResults.loaded >= 1", timeout=30000)
    page.locator(f"#trials tr[data-trial='{with_emg}'] button.open").click()
    _until(page, f"window.exostudyEmgPanel.trialId === {with_emg} && "
           "window.exostudyEmgPanel.loaded", 30)
    assert page.get_attribute("#emg-panel", "data-state") == "loaded"
    assert "2 lifts (segments)" in page.inner_text("#emg-panel-msg")
    assert page.locator("#emg-plot canvas").count() >= 1
    rows = page.locator("#emg-lifts tbody tr")
    assert rows.count() == 2
    cells = rows.nth(0).locator("td").all_inner_texts()
    assert cells[:4] == ["1", "squat", "0.50", "1.50"]
    peaks = [float(rows.nth(k).locator("td[data-channel='ES-L']").get_attribute("data-peak"))
             for k in range(2)]
    assert peaks[0] == pytest.approx(2 * BUMP_V / np.pi * 1e6, rel=0.03)
    assert peaks[1] == pytest.approx(2 * BASE_V / np.pi * 1e6, rel=0.03)
    assert rows.nth(0).locator("td[data-channel='ES-L']").inner_text() == f"{peaks[0]:.1f}"

    # A trial no recording covers says so, and shows no stale plot.
    page.locator(f"#trials tr[data-trial='{without}'] button.open").click()
    _until(page, f"window.exostudyEmgPanel.trialId === {without} && "
           "window.exostudyEmgPanel.error !== null", 30)
    assert page.get_attribute("#emg-panel", "data-state") == "none"
    assert f"trial {without} has no EMG" in page.inner_text("#emg-panel-msg")
    assert page.locator("#emg-plot canvas").count() == 0
    assert page.is_hidden("#emg-lifts")


# ------------------------------------------------------------------ MVC buttons
def test_mvc_buttons_time_the_repetitions_and_store_their_markers(
        page: Any, server: str, experimenter: dict[str, str]) -> None:
    api = _api(server, experimenter)
    _, sess = _session(api, "MVC")
    log_in_through(page, server, f"/console/sessions/{sess}", experimenter)
    _until(page, "window.exostudyMvc && window.exostudyMvc.ready", 30)
    # The muscles offered are the montage's.
    assert page.locator("#mvc-muscle option").all_inner_texts() == [
        "erector spinae (lumbar)", "gluteus maximus"]
    page.select_option("#mvc-muscle", "gluteus_maximus")
    page.select_option("#mvc-side", "left")
    page.fill("#mvc-reps", "2")
    # Contractions of 5 s: long enough that the early stop below lands inside the second
    # one on a loaded machine (at 1 s, a click that took longer found the button gone).
    page.fill("#mvc-contraction", "5")
    page.fill("#mvc-rest", "0")
    page.click("#mvc-add")
    page.click("#mvc-plan-save")
    page.locator("#mvc-msg", has_text="planned 1 MVC steps").wait_for(timeout=10_000)
    steps = _ok(api.get(f"/api/sessions/{sess}/mvc-steps"))
    assert [(s["muscle"], s["side"], s["repetitions"], s["contraction_s"], s["rest_s"])
            for s in steps] == [("gluteus_maximus", "left", 2, 5.0, 0.0)]
    row = page.locator(f"#mvc-steps tr[data-step='{steps[0]['id']}']")
    assert row.locator(".mvc-done").inner_text() == "0 of 2 done"

    row.locator("button.mvc-start").click()
    page.wait_for_selector("#mvc-timer[data-phase='ready']", timeout=5_000)
    assert "get ready" in page.inner_text("#mvc-timer")
    assert row.locator("button.mvc-start").is_disabled()  # one repetition at a time
    page.wait_for_selector("#mvc-timer[data-phase='contract']", timeout=10_000)
    assert "CONTRACT" in page.inner_text("#mvc-timer")
    page.wait_for_selector("#mvc-timer[data-phase='idle']", timeout=20_000)
    page.locator(".mvc-done", has_text="1 of 2 done").wait_for(timeout=5_000)
    # The second: stopped early by the experimenter.
    row.locator("button.mvc-start").click()
    page.wait_for_selector("#mvc-timer[data-phase='contract']", timeout=10_000)
    page.click("#mvc-stop")
    page.locator(".mvc-done", has_text="2 of 2 done").wait_for(timeout=10_000)
    assert row.locator("button.mvc-start").inner_text() == "done"
    assert row.locator("button.mvc-start").is_disabled()

    stored = _ok(api.get(f"/api/sessions/{sess}/mvc-steps"))[0]["repetitions_done"]
    assert [r["rep"] for r in stored] == [1, 2]
    markers = {m["id"]: m for m in _ok(api.get(f"/api/sessions/{sess}/markers"))}
    for r in stored:
        start, stop = markers[r["start_marker_id"]], markers[r["stop_marker_id"]]
        assert (start["label"], stop["label"]) == ("mvc_start", "mvc_stop")
        assert start["note"] == stop["note"] == f"gluteus_maximus left rep {r['rep']}"
        assert stop["lsl_time"] > start["lsl_time"]
    # Planned steps with a repetition run are data: the plan can no longer be replaced.
    assert page.is_disabled("#mvc-plan-save") or page.is_hidden("#mvc-plan-save")
