"""Processes that cannot be orphaned, and a server that cleans up after its predecessor.

The server runs as users start it (`exostudy serve`, a separate process) with the
device simulator it spawns on UDP; the faults are real signals to real processes.
"""

from __future__ import annotations

import signal
import socket
import time
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.models import Run
from backend.live import device_process
from backend.live.runtime import Runtime
from backend.main import create_app
from controller.device.auth import load_or_create_key
from tests.faults.served import alive, make_trials, serve, stored_ticks
from tests.login import USERNAME, bearer
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow


def _rows(db_url: str, trial_id: int) -> tuple[Trial, Run]:
    engine = make_engine(db_url)
    with Session(engine) as db:
        trial = db.get(Trial, trial_id)
        assert trial is not None and trial.run_id is not None
        run = db.get(Run, trial.run_id)
        assert run is not None
        db.expunge_all()
    engine.dispose()
    return trial, run


def _healthy(s: Any) -> bool:
    h = s.health()
    return bool(h["status"] == "ok" and h["worker"]["ticks"] > 20)


def test_server_sigkill_mid_trial_then_restart(tmp_path: Path, db_url: str,
                                              experimenter: dict[str, str],
                                              default_sets: tuple[Path, Path]) -> None:
    first, second = make_trials(db_url, USERNAME, ("pec", "pec"))
    port = free_udp_port()
    pid_file = tmp_path / "var" / f"device-sim-{port}.pid"
    env = {"EXOSTUDY_DEVICE_SCRIPT": "squat-sequence"}
    with serve(tmp_path, db_url, default_sets, port, **env) as s:
        s.log_in(experimenter)
        wait_for(lambda: _healthy(s), 90, "the device's ticks")
        r = s.client.post(f"/api/trials/{first}/start", json={})
        assert r.status_code == 200, r.text
        run_id = r.json()["run_id"]
        wait_for(lambda: len(stored_ticks(db_url, run_id)) >= 200, 60, "2 s of the trial")
        sim = int(pid_file.read_text())
        worker = s.health()["worker"]["pid"]
        s.kill()
        # Nothing of the dead server keeps running: no simulator holding the port and
        # playing on, no worker commanding.
        wait_for(lambda: not alive(sim), 10, "the orphaned simulator to exit")
        wait_for(lambda: not alive(worker), 10, "the orphaned worker to exit")
    stored = len(stored_ticks(db_url, run_id))

    with serve(tmp_path, db_url, default_sets, port, **env) as s:
        s.log_in(experimenter)
        wait_for(lambda: _healthy(s), 90, "the new device's ticks")
        assert s.health()["worker"]["controller"] == "none"
        trial, run = _rows(db_url, first)
        assert trial.status == "interrupted" and "server stopped" in trial.end_reason
        assert trial.tick_count == stored and run.tick_count == stored > 0
        assert run.ended_at is not None
        # The dead trial blocks nothing: the next one starts.
        r = s.client.post(f"/api/trials/{second}/start", json={})
        assert r.status_code == 200, r.text
        assert int(pid_file.read_text()) != sim


@pytest.fixture
def udp_settings(settings: Settings, tmp_path: Path) -> Settings:
    """A server whose worker talks UDP to the simulator it spawns on a free port."""
    return settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{free_udp_port()}", "run_dir": tmp_path / "var",
        "device_key_file": tmp_path / "var" / "device.key",
        "device_script": "squat-sequence"})


def test_stale_simulator_is_reclaimed_and_a_taken_port_fails_loudly(
        udp_settings: Settings, db_url: str, experimenter: dict[str, str]) -> None:
    # A simulator an earlier server left (it is the test's child, so it outlives that
    # server here), named in the pid file.
    load_or_create_key(udp_settings.device_key_file)
    leftover = Runtime(udp_settings, make_engine(db_url))
    leftover.start_device_simulator()
    assert leftover.device_process is not None
    stale = leftover.device_process
    port = udp_settings.device_host_port[1]
    with TestClient(create_app(udp_settings)) as client:
        client.headers.update(bearer(client, experimenter))
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        assert stale.poll() is not None  # stopped before the new one bound the port
        wait_for(lambda: client.get("/api/health").json()["status"] == "ok", 90,
                 "the new simulator's ticks")
        assert runtime.device_process.pid != stale.pid

        # Someone else takes the port while the simulator is down: changing the
        # simulation must fail with the reason, not answer 200 and stream nothing.
        device_process.stop(runtime.device_process, runtime._device_pid_file())
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
            squatter.bind(("127.0.0.1", port))
            r = client.post("/api/worker/simulation", json={"seed": 3, "script": "walking"})
            assert r.status_code == 503 and "in use" in r.json()["detail"]
        r = client.post("/api/worker/simulation", json={"seed": 3, "script": "walking"})
        assert r.status_code == 200, r.text


def test_device_death_and_restart_mid_trial_flags_the_trial(
        udp_settings: Settings, db_url: str, experimenter: dict[str, str]) -> None:
    trial_id, = make_trials(db_url, USERNAME, ("pec",))
    with TestClient(create_app(udp_settings)) as client:
        client.headers.update(bearer(client, experimenter))
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        wait_for(lambda: client.get("/api/health").json()["status"] == "ok", 90, "ticks")
        r = client.post(f"/api/trials/{trial_id}/start", json={})
        assert r.status_code == 200, r.text
        run_id = r.json()["run_id"]
        wait_for(lambda: len(stored_ticks(db_url, run_id)) >= 300, 60, "3 s of the trial")
        runtime.device_process.send_signal(signal.SIGKILL)
        runtime.device_process.wait(10)
        wait_for(lambda: not client.get("/api/health").json()["device"]["alive"], 10,
                 "the device loss")
        before = len(stored_ticks(db_url, run_id))
        time.sleep(0.5)  # the device stays away a while (its clock restarts at 0)
        runtime.start_device_simulator()
        wait_for(lambda: len(stored_ticks(db_url, run_id)) >= before + 200, 60,
                 "ticks from the restarted device")
        r = client.post(f"/api/trials/{trial_id}/stop", json={"outcome": "completed"})
        assert r.status_code == 200, r.text
        flags = r.json()["quality_flags"]
        t = stored_ticks(db_url, run_id)
        assert r.json()["tick_count"] == len(t)
    back = [b - a for a, b in zip(t, t[1:], strict=False) if b <= a]
    assert flags["time_backwards"] == len(back) >= 1
    assert flags["largest_backstep_s"] == pytest.approx(-min(back), abs=1e-6)
