"""The experimenter's console in a real browser: studies and participants, a data
collection (record, segment, drag an edge, fit models), an evaluation (utilities, plan,
a PEC trial with the state strip) and the replay of a stored trial."""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import ModelSetRecord, UtilitySetRecord
from tests.browser.conftest import SharedServer, shared_server
from tests.browser.login_page import log_in_through
from tests.databases import AccountTemplates
from tests.polling import wait_for

#: Numbers the studies that `_session` makes.
_STUDIES = itertools.count(1)
#: The simulated wearer's pace: five times real time (device time still steps 10 ms).
SPEED = 5.0


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[SharedServer]:
    """One real server and worker for the module: each test makes its own study and
    session, and puts the simulated wearer back to squatting (`fast_server`)."""
    with shared_server(tmp_path_factory.mktemp("console"), default_sets, account_templates,
                       start_worker=True, device_speed=SPEED,
                       device_script="squat-sequence") as s:
        yield s


@pytest.fixture
def settings(shared: SharedServer) -> Settings:
    return shared.settings


@pytest.fixture
def db_url(shared: SharedServer) -> str:
    return shared.settings.database_url


@pytest.fixture
def experimenter(shared: SharedServer) -> dict[str, str]:
    return shared.login


@pytest.fixture
def fast_server(shared: SharedServer) -> str:
    """The shared server, its simulated wearer squatting five times faster than real
    time from the start of a new run, as on a server started for the test (409 if an
    earlier test left a trial or recording running)."""
    _wearer(_api(shared.url, shared.login), SPEED, shared.settings.device_seed)
    return shared.url


@pytest.fixture
def server(fast_server: str) -> str:
    return fast_server


def _api(server: str, experimenter: dict[str, str]) -> httpx.Client:
    api = httpx.Client(base_url=server, timeout=30)
    token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    return api


def _ok(r: httpx.Response) -> Any:
    assert r.is_success, r.text
    return r.json()


def _session(api: httpx.Client, kind: str, participants: int = 1) -> tuple[int, int]:
    """A study of its own (names are unique on the shared server), `participants`
    participants and a session of `kind` for the first: (study id, session id)."""
    sid = _ok(api.post("/api/studies", json={"name": f"console {kind} {next(_STUDIES)}"}))["id"]
    pid = 0
    for n in range(participants):
        pid = _ok(api.post(f"/api/studies/{sid}/participants", json={"code": f"P0{n + 1}"}))["id"]
    first = _ok(api.get(f"/api/studies/{sid}/participants"))[0]["id"]
    sess = _ok(api.post(f"/api/participants/{first}/sessions",
                        json={"kind": kind, "precompression_pct": 25}))
    return sid, sess["id"] if pid else 0


def _wait_ticks(api: httpx.Client, ticks: int = 20, controller: str | None = None) -> None:
    """Until the worker's current run (of `controller`, if given) has `ticks` ticks."""
    def done() -> bool:
        worker = api.get("/api/health").json()["worker"]
        return worker["ticks"] >= ticks and controller in (None, worker["controller"])

    wait_for(done, 60, f"{ticks} ticks of the worker's run", poll=0.2)


def _wearer(api: httpx.Client, speed: float, seed: int = 1) -> None:
    """Start the simulated wearer's squats again (a new run) at `speed` times real time
    (409 while a trial or recording runs)."""
    _ok(api.post("/api/worker/simulation", json={"seed": seed, "script": "squat-sequence",
                                                 "speed": speed}))


def _pec_trial(api: httpx.Client, session_id: int, ticks: int) -> int:
    """Plan the session's squat trials, run the PEC trial for `ticks` ticks of the
    device, stop it; its id. The wearer squats twenty times faster than real time for
    it (the trial is counted in ticks: only the wait is shorter), then five times."""
    _wearer(api, 4 * SPEED)
    trials = _ok(api.post(f"/api/sessions/{session_id}/trials/plan",
                          json={"tasks": ["squat-sequence"]}))
    pec = next(t for t in trials if t["controller"] == "pec")
    _wait_ticks(api)
    _ok(api.post(f"/api/trials/{pec['id']}/start", json={}))
    _wait_ticks(api, ticks, controller="pec")
    _ok(api.post(f"/api/trials/{pec['id']}/stop", json={"outcome": "completed"}))
    _wearer(api, SPEED)  # five times real time again: every later tick is stored too
    return int(pec["id"])


def test_log_in_create_a_study_and_a_participant_with_a_session(
    server: str, page: Any, experimenter: dict[str, str]
) -> None:
    log_in_through(page, server, "/console", experimenter)
    page.fill("#study-name", "Lifting study")
    page.fill("#study-description", "UMC against PEC")
    page.click("#study-create")
    page.wait_for_url("**/console/studies/*")
    page.wait_for_selector("#study-title:has-text('Lifting study')")

    page.fill("#p-code", "P01")
    page.fill("#participant-form input[name=age]", "30")
    page.select_option("#participant-form select[name=sex]", "female")
    page.fill("#participant-form input[name=height_m]", "1.7")
    page.fill("#participant-form input[name=mass_kg]", "65")
    page.fill("#p-consent", "2026-11-20")
    page.click("#participant-create")
    page.wait_for_selector("#participants tr[data-participant=P01]")
    assert "2026-11-20" in page.inner_text("#participants tr[data-participant=P01] .consent")

    # Edit: the consent date moves, the mass changes.
    page.fill("#edit-consent", "2026-11-21")
    page.fill("#edit-form input[name=mass_kg]", "66.5")
    page.click("#edit-save")
    page.wait_for_selector("#edit-msg.msg-ok")
    row = page.inner_text("#participants tr[data-participant=P01]")
    assert "2026-11-21" in row and "66.5 kg" in row

    # A data collection session at 30 % precompression opens its own page.
    page.select_option("#s-kind", "data_collection")
    page.fill("#s-pct", "30")
    page.click("#session-create")
    page.wait_for_selector("#sessions .session-link")
    assert "30 %" in page.inner_text("#sessions")
    page.click("#sessions .session-link")
    page.wait_for_url("**/console/sessions/*")
    page.wait_for_function("window.exostudySession && window.exostudySession.ready")
    assert "P01" in page.inner_text("#session-title")
    assert page.is_visible("#record-step") and not page.is_visible("#plan-step")

    # The studies list shows the new study.
    page.goto(f"{server}/console")
    page.wait_for_selector("#studies tr[data-study] a")
    assert "Lifting study" in page.inner_text("#studies")


def _record(page: Any, api: httpx.Client, script: str, seconds: float) -> None:
    """Record `seconds` of device time of `script` from the page (waiting on the
    worker's ticks, not the clock: as much data on a busy machine as on a quiet one)."""
    page.select_option("#sim-script", script)
    page.click("#sim-apply")
    page.wait_for_selector("#sim-msg.msg-ok")
    _wait_ticks(api)
    page.fill("#rec-label", script)
    page.click("#rec-start")
    page.wait_for_selector("#rec-state[data-recording=true]")
    started = api.get("/api/health").json()["worker"]["ticks"]
    _wait_ticks(api, started + round(seconds * 100))
    before = page.evaluate("window.exostudySession.shownRecording")
    page.click("#rec-stop")
    page.wait_for_function(
        f"window.exostudySession.shownRecording !== {before if before else 'null'}"
        " && window.exostudySession.segments.length > 0", timeout=15000)


def test_record_segment_drag_an_edge_and_fit_models(
    fast_server: str, page: Any, experimenter: dict[str, str], settings: Settings
) -> None:
    api = _api(fast_server, experimenter)
    # A recording holds device time (`_record` waits on ticks): a wearer four times
    # faster again records the same samples in a quarter of the time (the page's
    # changes of the simulated wearer keep the speed).
    _wearer(api, 4 * SPEED, settings.device_seed)
    _, session_id = _session(api, "data_collection")
    log_in_through(page, fast_server, f"/console/sessions/{session_id}", experimenter)
    page.wait_for_function("window.exostudySession.ready && window.exostudySession.samples > 0",
                           timeout=20000)
    page.wait_for_selector("#sim-form:not([hidden])")

    _record(page, api, "squat-sequence", 35)
    labels = page.evaluate("window.exostudySession.segments.map(s => s.label)")
    assert "squat" in labels
    assert page.locator("#segments tbody tr").count() == len(labels)
    # The segments are drawn: the plot's canvas is not blank over the first band.
    seg = page.evaluate("window.exostudySession.segments[0]")
    page.locator("#seg-plot").scroll_into_view_if_needed()
    point = page.evaluate(f"window.exostudySession.edgeClientPoint({seg['id']}, 'end')")
    assert point is not None

    # Drag the first lift's end edge 40 px to the left: it becomes "edited".
    page.mouse.move(point["x"], point["y"])
    page.mouse.down()
    page.mouse.move(point["x"] - 20, point["y"], steps=4)
    page.mouse.move(point["x"] - 40, point["y"], steps=4)
    page.mouse.up()
    page.wait_for_selector(f"#segments tr[data-segment='{seg['id']}'][data-source=edited]")
    moved = page.evaluate(f"window.exostudySession.segments.find(s => s.id === {seg['id']})")
    assert moved["end"] < seg["end"]
    stored = _ok(api.get(f"/api/recordings/{page.evaluate('window.exostudySession.shownRecording')}"
                         "/segments"))
    assert next(s for s in stored if s["id"] == seg["id"])["end"] == moved["end"]

    _record(page, api, "stoop-sequence", 60)
    assert page.is_enabled("#fit-run"), page.inner_text("#fit-counts")
    page.click("#fit-run")
    page.wait_for_selector("#fit-progress[data-status=done]", timeout=30000)
    page.wait_for_function("window.exostudySession.modelSetDrawn !== null")
    inked = page.evaluate("""() => {
        const c = document.getElementById('model-plot');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 0; i < d.length; i += 4) if (d[i] < 200 || d[i + 2] < 200) n++;
        return n; }""")
    assert inked > 2000, f"the ellipses plot is nearly blank ({inked} pixels)"
    assert page.get_attribute("#model-plot", "data-models") == "3"


def test_plan_and_run_a_pec_trial_with_utilities_and_the_state_strip(
    fast_server: str, page: Any, experimenter: dict[str, str]
) -> None:
    api = _api(fast_server, experimenter)
    _, session_id = _session(api, "evaluation")
    log_in_through(page, fast_server, f"/console/sessions/{session_id}", experimenter)
    page.wait_for_function("window.exostudySession.ready && window.exostudySession.samples > 0",
                           timeout=20000)

    # Utilities at the session's precompression, recomputed when it changes.
    page.click("#util-run")
    page.wait_for_function("window.exostudySession.utilityCurvesFor === 25", timeout=20000)
    page.fill("#pct", "30")
    page.click("#pct-save")
    page.wait_for_function("window.exostudySession.utilityCurvesFor === 30", timeout=20000)

    # The stillness indicator reads the live stream.
    page.wait_for_function("window.exostudySession.stillness !== null")
    assert page.get_attribute("#stillness", "data-still") in ("true", "false")

    # Plan: squats only; the first participant gets UMC, PEC, then E-UMC.
    for task in ("stoop-sequence", "walking", "stairs"):
        page.uncheck(f"input[name=task][value={task}]")
    page.click("#plan-run")
    page.wait_for_selector("#trials tbody tr")
    order = page.eval_on_selector_all("#trials tbody tr",
                                      "rows => rows.map(r => r.dataset.controller)")
    assert order == ["umc", "pec", "eumc"]
    assert page.is_disabled("#plan-run")
    # The plan's blinded labels are at once the questionnaire step's conditions.
    page.wait_for_function(
        "document.querySelectorAll('#link-choices tr[data-condition]').length === 3")
    labels = page.eval_on_selector_all(
        "#trials tbody tr", "rows => rows.map(r => r.cells[2].innerText.replace('setting ', ''))")
    shown = page.eval_on_selector_all("#link-choices tr[data-condition]",
                                      "rows => rows.map(r => r.dataset.condition)")
    assert sorted(shown) == sorted(labels)

    page.click("#trials tr[data-controller=pec] button.start")
    page.wait_for_selector("#trials tr[data-controller=pec][data-status=running]")
    page.wait_for_function("window.exostudySession.strip.lockChanges >= 2", timeout=20000)
    page.wait_for_selector("#strip-left[data-lock=on]", timeout=10000)
    page.click("#trials tr[data-controller=pec] button.complete")
    page.wait_for_selector("#trials tr[data-controller=pec][data-status=completed]")
    assert page.is_visible("#trials tr[data-controller=pec] a.replay")


def _model_and_utility_sets(settings: Settings, study_id: int) -> tuple[int, int]:
    """The default model and utility sets stored in the study, as a fitted study has."""
    models = json.loads(Path(settings.models_path).read_text())
    utilities = json.loads(next(Path(settings.utilities_dir).glob("*.json")).read_text())
    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as db:
            ms = ModelSetRecord(study_id=study_id, name="defaults", status="ready",
                                document=models)
            us = UtilitySetRecord(study_id=study_id, name="defaults", precompression_pct=25,
                                  human_source="simulated", status="ready", document=utilities)
            db.add_all([ms, us])
            db.commit()
            return ms.id, us.id
    finally:
        engine.dispose()


def test_run_an_eumc_trial_and_watch_posteriors_progress_and_locks_change(
    fast_server: str, page: Any, experimenter: dict[str, str], settings: Settings
) -> None:
    api = _api(fast_server, experimenter)
    study_id, session_id = _session(api, "evaluation")
    ms_id, us_id = _model_and_utility_sets(settings, study_id)
    _ok(api.post(f"/api/sessions/{session_id}/trials/plan",
                 json={"tasks": ["squat-sequence"], "model_set_id": ms_id,
                       "utility_set_id": us_id}))
    _wait_ticks(api)

    # The session page's calibration step: one second of standing still. The simulated
    # wearer squats between stands, so the page waits for its stillness indicator and
    # tries again while the wearer moves.
    log_in_through(page, fast_server, f"/console/sessions/{session_id}", experimenter)
    page.wait_for_function("window.exostudySession.ready && window.exostudySession.samples > 0",
                           timeout=20000)
    assert page.is_visible("#calib-step")
    page.select_option("#calib-seconds", "1")
    page.check("#calib-retry")
    page.click("#calib-run")
    page.wait_for_selector("#calib-msg.msg-ok", timeout=40000)
    cal = page.evaluate("window.exostudySession.calibration")
    assert cal["ok"] is True and cal["attempts"] >= 1
    assert cal["samples"] == 100  # 1 s at 100 Hz
    assert cal["std_left_deg"] < 1.0 and cal["std_right_deg"] < 1.0
    assert f"{cal['offset_left_deg']:.1f}°" in page.inner_text("#calib-msg")

    page.wait_for_selector("#trials tr[data-controller=eumc] button.start")
    page.click("#trials tr[data-controller=eumc] button.start")
    page.wait_for_selector("#trials tr[data-controller=eumc][data-status=running]")

    # The live view: posteriors rise above 0.5, the squat model leads and shows its
    # progress, and the lock strip sees the locks come and go.
    page.goto(f"{fast_server}/live")
    page.wait_for_function("window.exostudyLive.strip.lockChanges >= 2", timeout=40000)
    page.wait_for_function("(window.exostudyLive.posteriorMax.squat ?? 0) > 0.5", timeout=20000)
    live = page.evaluate("({p: exostudyLive.posteriorMax, lead: exostudyLive.leading, "
                         "prog: exostudyLive.progressMax, changes: exostudyLive.leaderChanges})")
    assert 0.5 < live["p"]["squat"] <= 1.0
    # The lead changes between squats (no estimate, or "other") and squats.
    assert live["changes"] >= 3
    assert live["lead"].get("squat", 0) > 0
    assert 0.0 < live["prog"] <= 1.0
    assert "controller eumc" in page.inner_text("#worker-state")

    page.goto(f"{fast_server}/console/sessions/{session_id}")
    page.click("#trials tr[data-controller=eumc] button.complete")
    page.wait_for_selector("#trials tr[data-controller=eumc][data-status=completed]")
    trial = next(t for t in _ok(api.get(f"/api/sessions/{session_id}/trials"))
                 if t["controller"] == "eumc")
    # The trial ran with the offsets the page showed (radians stored, degrees shown).
    left, right = trial["config_snapshot"]["settings"]["calibration"]
    assert math.degrees(left) == pytest.approx(cal["offset_left_deg"], abs=1e-9)
    assert math.degrees(right) == pytest.approx(cal["offset_right_deg"], abs=1e-9)


def test_replay_a_stored_trial_and_scrub_it(
    fast_server: str, page: Any, experimenter: dict[str, str]
) -> None:
    api = _api(fast_server, experimenter)
    _, session_id = _session(api, "evaluation")
    pec = {"id": _pec_trial(api, session_id, 2000)}  # 20 s of squats
    cols = _ok(api.get(f"/api/trials/{pec['id']}/ticks.json"))["columns"]
    locked_at = next(i for i, v in enumerate(cols["lock_left"]) if v)

    log_in_through(page, fast_server, f"/console/sessions/{session_id}", experimenter)
    page.wait_for_selector(f"#trials tr[data-trial='{pec['id']}'] a.replay")
    page.click(f"#trials tr[data-trial='{pec['id']}'] a.replay")
    page.wait_for_url(f"**/live?trial={pec['id']}")
    page.wait_for_function("window.exostudyLive.replay && window.exostudyLive.replay.loaded")
    assert page.evaluate("window.exostudyLive.replay.samples") == len(cols["t"])
    assert "PEC" in page.inner_text("#mode-text")

    def scrub(index: int) -> None:
        page.eval_on_selector("#scrub", "(el, i) => { el.value = String(i); "
                              "el.dispatchEvent(new Event('input')); }", index)

    scrub(locked_at)
    assert page.get_attribute("#strip-left", "data-lock") == "on"
    scrub(0)
    assert page.get_attribute("#strip-left", "data-lock") == "off"
    assert page.evaluate("window.exostudyLive.replay.index") == 0
    draws = page.evaluate("window.exostudyLive.draws")
    scrub(len(cols["t"]) - 1)
    assert page.evaluate("window.exostudyLive.draws") > draws
    page.select_option("#window", "30")
    assert page.inner_text("#window-s") == "30"
