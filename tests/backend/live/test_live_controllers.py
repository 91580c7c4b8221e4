"""Controllers live: the worker switches controller on request, E-UMC refuses to lock
until calibrated, and lock commands and posteriors reach the browser stream and the
database."""

from __future__ import annotations

import json
import time

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.models import Run, ticks_table
from backend.main import create_app
from controller.tick_record import TickFlag
from tests.login import log_in
from tests.polling import wait_for

pytestmark = pytest.mark.slow


def _squat_locked(database_url: str) -> bool:
    """The latest run has stored a tick that recognised a squat and one that locked both
    sides."""
    engine = make_engine(database_url)
    with engine.connect() as conn:
        run_id = conn.execute(select(func.max(Run.id))).scalar_one()
        c = ticks_table.c
        recognised = conn.execute(select(func.count()).where(
            c.run_id == run_id, c.controller_ran.is_(True), c.post_squat > 0.5)).scalar_one()
        locked = conn.execute(select(func.count()).where(
            c.run_id == run_id, c.lock_left.is_(True), c.lock_right.is_(True))).scalar_one()
    engine.dispose()
    return bool(recognised and locked)


def test_pec_then_eumc_with_calibration(settings: Settings, experimenter: dict[str, str]
                                       ) -> None:
    settings = settings.model_copy(update={"start_worker": True, "controller": "pec",
                                           "device_script": "squat-sequence"})
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 10, 60, "ticks")
        # PEC: the lock command follows the velocity trigger (both hips >= 1 rad/s).
        with client.websocket_connect("/ws/live") as ws:
            trig_lock: list[tuple[bool, bool]] = []
            start = time.monotonic()
            while time.monotonic() - start < 12 and sum(t for t, _ in trig_lock) < 5:
                msg = json.loads(ws.receive_text())
                if msg["type"] == "ticks":
                    c = msg["columns"]
                    trig_lock += list(zip(c["trigger"], c["lock_left"], strict=True))
        assert sum(t for t, _ in trig_lock) >= 5, "no squat triggered the PEC"
        assert all(lock for trig, lock in trig_lock if trig)

        r = client.post("/api/worker/controller", json={"name": "eumc"})
        assert r.status_code == 200
        wait_for(lambda: client.get("/api/health").json()["worker"]["controller"] == "eumc", 30,
              "the E-UMC")
        # Calibrate while the wearer stands between squats (retry if they were moving).
        outcome = None
        for _ in range(12):
            r = client.post("/api/worker/calibrate", json={"seconds": 1.0})
            if r.status_code == 200:
                outcome = r.json()
                break
            # Moving, or held still at the bottom of a squat (not standing): try again.
            assert r.status_code == 422 and any(
                why in r.json()["detail"]["message"] for why in ("not still", "not standing"))
        assert outcome is not None and outcome["ok"]
        assert abs(outcome["offset_left_deg"]) < 15 and outcome["std_left_deg"] < 1.0
        # Squats with the calibrated E-UMC, until one is recognised and locked.
        wait_for(lambda: _squat_locked(settings.database_url), 120,
                 "a squat recognised and locked by the calibrated E-UMC", poll=0.5)
        # Another virtual participant: the calibration was not made on them, so the
        # running E-UMC goes on uncalibrated (it never locks) rather than with offsets
        # measured on someone else.
        swapped = client.post("/api/worker/simulation",
                              json={"seed": 77, "script": "squat-sequence"})
        assert swapped.status_code == 200, swapped.text
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 800, 120,
                 "8 s of the new wearer's squats", poll=0.5)

    engine = make_engine(settings.database_url)
    with engine.connect() as conn:
        runs = conn.execute(select(Run).order_by(Run.id)).all()
        controllers = [r.controller for r in runs]
        assert controllers[:2] == ["pec", "eumc"] and controllers[-2:] == ["eumc", "eumc"]
        calibrated, other_wearer = runs[-2], runs[-1]
        assert json.loads(other_wearer.config_json)["settings"]["calibration"] is None
        other_ticks = conn.execute(
            select(ticks_table.c.flags, ticks_table.c.lock_left, ticks_table.c.lock_right)
            .where(ticks_table.c.run_id == other_wearer.id)).all()
        assert json.loads(calibrated.config_json)["settings"]["calibration"] is not None
        uncalibrated_flags = conn.execute(
            select(ticks_table.c.flags, ticks_table.c.lock_left)
            .where(ticks_table.c.run_id == runs[1].id)
        ).all()
        ticks = conn.execute(
            select(ticks_table).where(ticks_table.c.run_id == calibrated.id)
        ).mappings().all()
    engine.dispose()
    assert all(f & TickFlag.NOT_CALIBRATED and not lock for f, lock in uncalibrated_flags)
    assert len(other_ticks) >= 500
    assert all(f & TickFlag.NOT_CALIBRATED and not (left or right)
               for f, left, right in other_ticks)
    ran = [t for t in ticks if t["controller_ran"] and t["post_squat"] is not None]
    assert ran, "the calibrated E-UMC never evaluated the UMC"
    assert max(t["post_squat"] for t in ran) > 0.5
    assert any(t["lock_left"] and t["lock_right"] for t in ticks)
    # It never runs the UMC while the trigger is off.
    assert all(t["trigger"] for t in ticks if t["post_squat"] is not None)
