"""Controller settings that cannot be proved safe never reach the exoskeleton.

On the real server (worker process, simulated exoskeleton as a UDP device process),
every route that takes settings answers 422 naming the field, and the worker process
itself refuses a configuration it receives unchecked and stays unlocked. Before the
typed specification, `{"velocity_threshold": -1}` was accepted and the PEC locked on
407 of 432 ticks of a walking wearer; NaN silently disabled the trigger."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from controller.controllers.spec import ControllerSpec
from controller.device.auth import create_key
from tests.backend.worker.unchecked import unchecked_spec
from tests.faults.device_rig import Worker, device_process, locked_ticks
from tests.faults.served import make_trials
from tests.login import USERNAME, bearer
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow

#: (raw JSON of one setting, the field the 422 must name, a word of its message)
BAD_SETTINGS: list[tuple[str, str, str]] = [
    ('{"velocity_threshold": -1}', "velocity_threshold", "(0, 20]"),
    ('{"velocity_threshold": NaN}', "velocity_threshold", "finite"),
    ('{"velocity_threshold": 1e999}', "velocity_threshold", "finite"),
    ('{"velocity_threshold": "fast"}', "velocity_threshold", "number"),
    ('{"pec_rate_hz": 30}', "pec_rate_hz", "divide"),
    ('{"priors": [0.5, 0.5, 0.5, 0.5]}', "priors", "sum to 1"),
    ('{"hold_s": 30}', "hold_s", "[0.01, 1]"),
    ('{"accel_std": 0}', "accel_std", "(0, 1000]"),
    ('{"window": 2.5}', "window", "integer"),
    ('{"lock_threshold": 1}', "lock_threshold", "unknown"),
]


@pytest.fixture
def live(settings: Settings, experimenter: dict[str, str], tmp_path: Path
         ) -> Iterator[TestClient]:
    """The server with its worker on a spawned UDP device process (a walking wearer)."""
    key_file = tmp_path / "device.key"
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{free_udp_port()}", "device_script": "walking",
        "device_key_file": key_file, "run_dir": tmp_path})
    with TestClient(create_app(settings)) as client:
        client.headers.update(bearer(client, experimenter))
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 20, 120,
                 "the worker's first ticks")
        yield client


def _post_raw(client: TestClient, url: str, body: str) -> Any:
    return client.post(url, content=body.encode(), headers={"Content-Type": "application/json"})


def test_every_settings_route_names_the_bad_field(live: TestClient, settings: Settings) -> None:
    for raw, field, word in BAD_SETTINGS:
        r = _post_raw(live, "/api/worker/controller", f'{{"name": "pec", "config": {raw}}}')
        assert r.status_code == 422, (raw, r.text)
        (err,) = r.json()["detail"]
        assert err["loc"] == ["body", "config", field], raw
        assert word in err["msg"], (raw, err["msg"])
    health = live.get("/api/health").json()
    assert health["worker"]["controller"] == "none" and health["worker"]["alive"]
    assert not health["worker"]["errors"]  # nothing invalid ever reached the worker

    (trial,) = make_trials(settings.database_url, USERNAME, ("pec",), "walking")
    r = live.post(f"/api/trials/{trial}/start", json={"rate_hz": 30})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["body", "rate_hz"]
    assert "divide" in r.json()["detail"][0]["msg"]
    assert live.get(f"/api/trials/{trial}").json()["status"] == "planned"
    assert live.get("/api/health").json()["worker"]["controller"] == "none"


def test_what_if_names_the_bad_setting(client: TestClient, settings: Settings) -> None:
    from tests.backend.analysis.test_results import _setup

    ids = _setup(client, settings)
    for raw, field, word in BAD_SETTINGS:
        r = _post_raw(client, f"/api/trials/{ids['pec']}/what-if",
                      f'{{"controller": "pec", "settings": {raw}}}')
        assert r.status_code == 422, (raw, r.text)
        (err,) = r.json()["detail"]
        assert err["loc"] == ["body", "settings", field], raw
        assert word in err["msg"]
    r = client.post(f"/api/trials/{ids['pec']}/what-if", json={"controller": "pec",
                                                                "rate_hz": 30})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "rate_hz"]


def test_the_worker_refuses_what_it_cannot_prove_safe(tmp_path: Path) -> None:
    """The worker process validates again what it receives (here sent to it directly,
    past the server's checks): it starts, or falls back to, `none`, and never locks."""
    key_file = tmp_path / "device.key"
    create_key(key_file)
    port = free_udp_port()
    negative = {"settings": {"velocity_threshold": -1}}
    with device_process(port, key_file, "walking"), \
            Worker(port, key_file, "pec", negative) as worker:
        worker.wait_ticks(150)
        assert [r.controller for r in worker.runs] == ["none"]
        assert any("velocity_threshold" in e for e in worker.sup.state.errors)

        worker.sup.set_controller(ControllerSpec("pec"))  # a valid PEC: runs
        wait_for(lambda: worker.runs[-1].controller == "pec", 30, "the valid PEC")
        worker.wait_ticks(150)
        nan = json.loads('{"settings": {"velocity_threshold": NaN}}')
        assert math.isnan(nan["settings"]["velocity_threshold"])
        worker.sup.set_controller(unchecked_spec("pec", nan))  # refused: the PEC stops too
        wait_for(lambda: worker.runs[-1].controller == "none", 30, "the fall back to none")
        worker.wait_ticks(150)
        worker.sup.set_controller(unchecked_spec("pec", negative))
        wait_for(lambda: sum("rejected" in e for e in worker.sup.state.errors) >= 2, 30,
                 "the second refusal")
        worker.wait_ticks(150)
        ticks = worker.ticks()
        runs = [r.controller for r in worker.runs]

    assert runs == ["none", "pec", "none"]
    assert len(ticks) >= 600
    assert locked_ticks(ticks) == 0
    print(f"worker refusals: runs {runs}, {len(ticks)} walking ticks, "
          f"{locked_ticks(ticks)} locked")
