"""A recording that starts its simulated wearer: the recording holds the script from its
first sample at any simulator speed, and a request the server cannot honour is a 422
that changes nothing."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from tests.login import log_in
from tests.polling import wait_for
from tests.simulation_speed import past_run, ticks_per_second


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _session(client: TestClient) -> int:
    study = _ok(client.post("/api/studies", json={"name": "demos"}), 201)
    p = _ok(client.post(f"/api/studies/{study['id']}/participants",
                        json={"code": "D01", "age": 30, "sex": "female", "height_m": 1.7,
                              "mass_kg": 65, "consent_date": "2026-11-20"}), 201)
    return int(_ok(client.post(f"/api/participants/{p['id']}/sessions",
                               json={"kind": "data_collection",
                                     "precompression_pct": 25}), 201)["id"])


def test_the_recording_holds_the_wearer_from_the_scripts_first_sample(
        settings: Settings, experimenter: dict[str, str]) -> None:
    settings = settings.model_copy(update={"start_worker": True, "device_speed": 1.0,
                                           "device_script": "walking"})
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        sid = _session(client)
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 10, 60,
                 "the worker's ticks")
        # Refused before anything changes: an unknown script names its field.
        bad = client.post(f"/api/sessions/{sid}/recordings", json={
            "label": "x", "simulation": {"seed": 3, "script": "cartwheels", "speed": 50}})
        assert bad.status_code == 422, bad.text
        assert bad.json()["detail"][0]["loc"] == ["body", "simulation", "script"]
        assert _ok(client.get(f"/api/sessions/{sid}/recordings")) == []
        assert client.get("/api/health").json()["worker"]["controller"] == "none"
        # A live wearer's recording is not timed.
        timed = client.post(f"/api/sessions/{sid}/recordings", json={"duration_s": 10})
        assert timed.status_code == 422, timed.text
        assert timed.json()["detail"][0]["loc"] == ["body", "duration_s"]
        assert _ok(client.get(f"/api/sessions/{sid}/recordings")) == []

        # At 100x the script runs ahead by seconds of device time while a second request
        # starts a recording; started together, the recording begins at its first sample.
        # Timed: the worker ends it after 30 s of device time, though the stop comes late.
        rec = _ok(client.post(f"/api/sessions/{sid}/recordings", json={
            "label": "squats", "duration_s": 30.0,
            "simulation": {"seed": 3, "script": "squat-sequence", "speed": 100}}), 201)
        wait_for(lambda: past_run(client, rec["run_id"], 3000), 120,
                 "the end of the recording's 30 s", poll=0.1)
        # Then the wearer goes on at real time: at 100x a second would be 10,000 ticks.
        assert ticks_per_second(client) < 2000  # real time, bursts after a stall included
        rec = _ok(client.post(f"/api/recordings/{rec['id']}/stop"))
        assert rec["last_tick_id"] - rec["first_tick_id"] + 1 == 3000
        angles = _ok(client.get(f"/api/recordings/{rec['id']}/angles"))
        assert angles["t"][0] == 0.0  # the device's first sample of the new wearer
        assert len(angles["t"]) == 3000 and angles["t"][-1] == pytest.approx(29.99)
        assert angles["t"][1] == pytest.approx(0.01)  # 100 Hz device time
        found = _ok(client.post(f"/api/recordings/{rec['id']}/segment"))
        assert len([s for s in found if s["label"] == "squat"]) >= 4
        # The first squat starts after the script's opening stand, not cut at sample 0.
        assert min(s["start"] for s in found) > 0
        # The server records what the worker runs: the recording's wearer and the speed
        # asked for it, which a wearer put on without a speed (or a restart) takes.
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        assert (runtime.settings.device_seed, runtime.settings.device_script,
                runtime.settings.device_speed) == (3, "squat-sequence", 100.0)

        # A worker that stops after a timed recording's end and before its stop: the
        # recording holds every sample it asked for, so it is stopped, not interrupted.
        # One still short of its time is interrupted.
        whole = _ok(client.post(f"/api/sessions/{sid}/recordings", json={
            "label": "whole", "duration_s": 2.0,
            "simulation": {"seed": 4, "script": "standing", "speed": 20}}), 201)
        wait_for(lambda: past_run(client, whole["run_id"], 200), 120,
                 "the end of the recording's 2 s", poll=0.1)
        _ok(client.post("/api/worker/restart"))
        whole = _ok(client.get(f"/api/recordings/{whole['id']}"))
        assert whole["status"] == "stopped"
        assert whole["last_tick_id"] - whole["first_tick_id"] + 1 == 200
        wait_for(lambda: client.get("/api/health").json()["worker"]["alive"], 60,
                 "the worker back")
        cut = _ok(client.post(f"/api/sessions/{sid}/recordings", json={
            "label": "cut", "duration_s": 600.0,
            "simulation": {"seed": 4, "script": "standing", "speed": 1}}), 201)
        _ok(client.post("/api/worker/restart"))
        assert _ok(client.get(f"/api/recordings/{cut['id']}"))["status"] == "interrupted"


def test_only_the_in_process_simulator_starts_a_wearer_with_a_recording(
        settings: Settings, experimenter: dict[str, str]) -> None:
    settings = settings.model_copy(update={"device_kind": "udp"})
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        sid = _session(client)
        r = client.post(f"/api/sessions/{sid}/recordings", json={
            "simulation": {"seed": 3, "script": "squat-sequence"}})
        assert r.status_code == 422, r.text
        detail = r.json()["detail"][0]
        assert detail["loc"] == ["body", "simulation"] and "'udp'" in detail["msg"]
        assert _ok(client.get(f"/api/sessions/{sid}/recordings")) == []


def test_a_refused_simulation_change_leaves_the_record_of_the_wearer(
        settings: Settings, experimenter: dict[str, str]) -> None:
    """The worker refuses a new wearer under a timed trial (the API's own checks refuse
    it sooner): the server's record stays the wearer the worker runs."""
    from controller.controllers.spec import ControllerSpec

    settings = settings.model_copy(update={"start_worker": True, "device_speed": 1.0,
                                           "device_seed": 2, "device_script": "walking"})
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 10, 60,
                 "the worker's ticks")
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        portal = client.portal  # the app's own event loop, as a request's
        assert portal is not None
        portal.call(lambda: runtime.switch_controller(ControllerSpec("pec"),
                                                      max_ticks=100_000))
        with pytest.raises(RuntimeError, match="simulated wearer cannot change"):
            portal.call(lambda: runtime.set_simulation(9, "squat-sequence", 50.0))
        assert (runtime.settings.device_seed, runtime.settings.device_script,
                runtime.settings.device_speed) == (2, "walking", 1.0)
        assert (runtime.supervisor.config.device_seed,
                runtime.supervisor.config.device_speed) == (2, 1.0)
