"""Learned priors never add a lock, on the running processes.

The real worker process runs the UMC on the simulated exoskeleton, during walking and
during stairs, with two stored prior sets as a trial gets them (`ControllerSpec` with
the `LearnedPriors` record): the most skewed
history there is (every lift confirmed as "stoop left", projected onto the safety
bound) and one from use with nothing confirmed (the EM estimate from posteriors that
all point at "stoop left"). Every UMC evaluation the worker made is then decided again
under equal priors from what the worker recorded at that tick (likelihoods and
progress, `prior_safety.lock_decided`, checked first to reproduce the worker's own
decisions exactly): no evaluation may lock under the learned priors that does not lock
under equal priors, so lock decisions, and the time locked, cannot exceed the equal
priors' on the same movement.

Priors from outside that are not safe are refused: the worker, sent them past the
server's checks (settings priors, and a record whose document claims looser roles),
runs `none` and never locks; the API answers 422 (`tests/backend/api/
test_personalisation_api.py` for prior sets, and the worker route here).

The wearer is the worker's own simulated device, sped up (`SIM_SPEED`), not a device
process on UDP paced at 100 Hz: a lock decision depends on the samples and the priors,
never on when a sample arrives, and a sped-up simulation skips no sample (a reader
that falls behind gets the samples due meanwhile, in order: `SimulatedDevice.read`;
it waits for a server that falls behind: `backend.worker.machine.hold`). So the worker
decides on the same 2,000 ticks of device time per run as at real time, and the two
runs of a test take about 2 s instead of 40. What the UDP link itself can do to a lock
(late, forged, replayed or dropped packets) is tested on device processes in
test_protocol_faults.py and test_link_attacks.py."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from backend.worker.messages import RunStarted, TickBatch, WorkerConfig
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.config import ControllerConfig
from controller.controllers.spec import ControllerSpec
from controller.intent.label_shift import learn_from_unconfirmed
from controller.intent.learned_priors import LearnedPriors, learn_from_confirmed
from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import PriorBounds, lock_decided
from controller.tick_record import MODEL_NAMES, Action, TickRecord
from tests.backend.worker.unchecked import unchecked_spec
from tests.login import bearer
from tests.polling import wait_for

pytestmark = pytest.mark.slow

#: Ticks per run (device time: 20 s of the wearer's movement).
RUN_TICKS = 2000
#: The simulated wearer this many times faster than real time (it skips no sample when
#: the worker falls behind, so every tick is decided on however busy the machine is).
SIM_SPEED = 20.0
STOOP_LEFT_SKEW = (0.05, 0.8, 0.05, 0.1)


class Runs:
    """The worker's ticks per run, and which controller each run had."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.ticks: dict[int, list[TickRecord]] = {}
        self.controller: dict[int, str] = {}
        self.order: list[int] = []

    def started(self, msg: RunStarted) -> None:
        with self.lock:
            self.controller[msg.run_token] = msg.controller
            self.order.append(msg.run_token)

    def batch(self, batch: TickBatch) -> None:
        with self.lock:
            self.ticks.setdefault(batch.run_token, []).extend(batch.records)

    def latest(self) -> tuple[int, str, int]:
        """(token, controller, ticks so far) of the newest run."""
        with self.lock:
            tok = self.order[-1] if self.order else -1
            return tok, self.controller.get(tok, ""), len(self.ticks.get(tok, []))


@contextmanager
def worker(script: str) -> Iterator[tuple[WorkerSupervisor, Runs]]:
    """The real worker process, its simulated wearer following `script` at `SIM_SPEED`."""
    runs = Runs()
    sup = WorkerSupervisor(
        WorkerConfig(device_kind="sim", device_seed=1, device_script=script,
                     device_speed=SIM_SPEED, spec=ControllerSpec("none"),
                     status_interval=0.1),
        WorkerCallbacks(on_ticks=runs.batch, on_run_started=runs.started))
    sup.start()
    try:
        yield sup, runs
    finally:
        sup.stop("test over")


def _run(sup: WorkerSupervisor, runs: Runs, spec: ControllerSpec, expect: str,
         ticks: int = RUN_TICKS) -> list[TickRecord]:
    """Switch to `spec`, wait for its run (controller `expect`) and `ticks` of it."""
    before = runs.latest()[0]
    sup.set_controller(spec)
    tok = wait_for(lambda: (t := runs.latest())[0] != before and t[1] == expect and t[0],
                   120, f"the {expect} run (worker errors {sup.state.errors})")
    wait_for(lambda: len(runs.ticks.get(tok, [])) >= ticks, 180,
             f"{ticks} ticks of the {expect} run")
    with runs.lock:
        return list(runs.ticks[tok][:ticks])


def _evaluations(records: list[TickRecord]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Progress, likelihoods and whether the worker decided a lock, per evaluation."""
    ran = [r for r in records if r.controller_ran]
    s = np.array([[getattr(r, f"s_curr_{m}") for m in MODEL_NAMES] for r in ran])
    p = np.array([[getattr(r, f"p_obs_{m}") for m in MODEL_NAMES] for r in ran])
    acted = np.array([r.action != int(Action.NO_LOCK) for r in ran])
    return s.reshape(-1, 3), np.nan_to_num(p.reshape(-1, 3), nan=0.0), acted


def _stored_prior_sets(bounds: PriorBounds) -> dict[str, LearnedPriors]:
    """The two adversarial histories, each as the app stores it (a JSON document)."""
    skewed = learn_from_confirmed(["stoop_left"] * 1000, bounds, version="skewed")
    post = np.tile([0.0, 1.0, 0.0, 0.0], (500, 1))
    unconfirmed = learn_from_unconfirmed(post, EQUAL_PRIORS, bounds, version="unconfirmed")
    return {k: LearnedPriors.from_json(json.loads(json.dumps(v.to_json())))
            for k, v in (("skewed", skewed), ("unconfirmed", unconfirmed))}


@pytest.mark.parametrize("script", ["walking", "stairs"])
def test_learned_priors_lock_no_more_than_equal_priors(
        script: str, default_sets: tuple[Path, Path]) -> None:
    models_path, utilities_dir = default_sets
    models = json.loads(models_path.read_text())
    utilities = json.loads(next(utilities_dir.glob("*.json")).read_text())
    table = np.asarray(utilities["utilities_nm2"], dtype=np.float64)
    bounds = PriorBounds.for_table(table)
    stored = _stored_prior_sets(bounds)
    assert stored["skewed"].estimate[1] > 0.9  # the history is as skewed as it gets
    sets = {"models": models, "utilities": utilities}
    found: dict[str, tuple[int, int, int]] = {}
    with worker(script) as (sup, runs):
        # Past the server's checks: unsafe settings priors, and a record whose document
        # claims roles that would allow them. The worker refuses both and stays unlocked.
        forged = {**stored["skewed"].to_json(), "values": list(STOOP_LEFT_SKEW),
                  "roles": ["neutral"] * 4}
        for bad in (unchecked_spec("umc", {**sets, "settings": {
                        "priors": list(STOOP_LEFT_SKEW)}}),
                    _with_record(unchecked_spec("umc", sets), forged)):
            refused = len(sup.state.errors)
            sup.set_controller(bad)

            def more(n: int = refused) -> bool:
                return len(sup.state.errors) > n

            wait_for(more, 120, "the worker's refusal")
            assert "priors" in sup.state.errors[-1], sup.state.errors[-1]
            wait_for(lambda: runs.latest()[1] == "none" and runs.latest()[2] > 100, 60,
                     "the fall back to none")
        with runs.lock:
            idle = [r for tok, recs in runs.ticks.items() for r in recs]
        assert sum(r.lock_left or r.lock_right for r in idle) == 0

        for name, priors in stored.items():
            spec = ControllerSpec("umc", ControllerConfig(), models=models,
                                  utilities=utilities, priors=priors)
            records = _run(sup, runs, spec, "umc")
            s, p, acted = _evaluations(records)
            assert s.shape[0] > 150, "too few evaluations to judge"
            mine = lock_decided(table, s, p, priors.values)
            # The re-decision is the worker's own decision, evaluation for evaluation ...
            assert np.array_equal(mine, acted), (name, int(mine.sum()), int(acted.sum()))
            equal = lock_decided(table, s, p, EQUAL_PRIORS)
            # ... and nothing the learned priors lock on is left unlocked by equal ones.
            assert not (mine & ~equal).any(), (name, np.flatnonzero(mine & ~equal)[:10])
            unbounded = lock_decided(table, s, p, STOOP_LEFT_SKEW)
            found[name] = (int(mine.sum()), int(equal.sum()), int(unbounded.sum()))
            held = sum(r.lock_left or r.lock_right for r in records)
            print(f"{script}, {name} priors {[round(v, 3) for v in priors.values]}: "
                  f"{s.shape[0]} evaluations, lock decisions {found[name][0]} (equal priors "
                  f"{found[name][1]}, unbounded skew {found[name][2]}), {held} ticks held")
    assert set(found) == {"skewed", "unconfirmed"}


def _with_record(spec: ControllerSpec, document: dict[str, Any]) -> ControllerSpec:
    """`spec` carrying a priors record built from `document` without its checks (what a
    stored row altered to claim looser roles would give), its values in the settings."""
    record = object.__new__(LearnedPriors)
    for k, v in LearnedPriors(version="x", values=EQUAL_PRIORS,
                              estimate=EQUAL_PRIORS).__dict__.items():
        object.__setattr__(record, k, v)
    object.__setattr__(record, "values", tuple(document["values"]))
    object.__setattr__(record, "roles", tuple(document["roles"]))
    object.__setattr__(spec, "priors", record)
    object.__setattr__(spec.settings, "priors", tuple(document["values"]))
    return spec


def test_the_worker_route_refuses_unsafe_priors(settings: Settings,
                                                experimenter: dict[str, str]) -> None:
    """POST /api/worker/controller with priors outside the bound: 422 naming them, and
    the worker keeps running `none`. The refusal is the server's, before anything
    reaches the worker, so the worker's own simulated wearer serves (no device process
    to start)."""
    settings = settings.model_copy(update={"start_worker": True,
                                           "device_script": "walking"})
    with TestClient(create_app(settings)) as client:
        client.headers.update(bearer(client, experimenter))
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 20, 120,
                 "the worker's first ticks")
        r = client.post("/api/worker/controller", json={
            "name": "umc", "config": {"priors": list(STOOP_LEFT_SKEW)}})
        assert r.status_code == 422, r.text
        (err,) = r.json()["detail"]
        assert err["loc"] == ["body", "config", "priors"]
        assert "lock where equal priors would not" in err["msg"]
        health = client.get("/api/health").json()["worker"]
        assert health["controller"] == "none" and not health["errors"]
