"""A controller added in one module and registered runs live (a real worker process on
the simulated device) and in the batch replay, with the same kernel code."""

from __future__ import annotations

import importlib
import threading
from collections.abc import Iterator
from types import ModuleType

import numpy as np
import pytest

from backend.worker.messages import RunStarted, TickBatch, WorkerConfig
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.controllers import registry
from controller.controllers.factory import controller_names, make_controller, needs_models
from controller.controllers.spec import ControllerSpec
from controller.runner.replay import AngleRecording, replay_columns, replay_per_tick
from controller.sim.recording import simulate_angles
from controller.tick_codec import columns, columns_from_records
from controller.tick_record import Action
from tests.polling import wait_for

MODULE = "tests.controller.controllers.constant_controller"


@pytest.fixture
def constant() -> Iterator[ModuleType]:
    """The constant controller registered for one test, then removed again (other tests
    check the list of controller names)."""
    mod = importlib.import_module(MODULE)  # importing it registers it
    if registry.lookup("constant") is None:  # removed after an earlier test
        importlib.reload(mod)
    yield mod
    registry.unregister("constant")


def test_registration_makes_a_name_valid_everywhere(constant: ModuleType) -> None:
    assert "constant" in controller_names() and not needs_models("constant")
    ctl = make_controller("constant", {"settings": {"extra": {"constant": 0.25}}})
    assert isinstance(ctl, constant.ConstantController)
    registry.unregister("constant")
    with pytest.raises(ValueError, match="unknown controller 'constant'"):
        make_controller("constant")
    with pytest.raises(ValueError, match="already registered"):
        registry.register("pec")(constant.build)
    with pytest.raises(ValueError, match="lowercase"):
        registry.register("Bad Name")


def test_a_controller_module_that_cannot_be_imported_is_named(
    monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(registry, "_loaded", False)
    monkeypatch.setenv(registry.ENV_MODULES, "tests.controller.no_such_controller")
    with pytest.raises(RuntimeError, match=r"EXOSTUDY_CONTROLLERS.*no_such_controller"):
        registry.names()


def test_a_registered_controller_replays_in_batch_and_per_tick(constant: ModuleType) -> None:
    run = simulate_angles(5, "squat-sequence")
    rec = AngleRecording(run.t[:1500], run.q[:1500], None, None)
    cfg = {"settings": {"extra": {"constant": 0.75}}}
    batch = replay_columns(rec, make_controller("constant", cfg))
    live = columns_from_records(replay_per_tick(rec, make_controller("constant", cfg),
                                                clock=lambda: 0.0))
    good = batch["flags"] == 0
    assert good.sum() > 1400
    assert np.all(batch["post_other"][good] == 0.75)
    assert np.all(batch["controller_ran"][good]) and np.all(batch["action"] == Action.NO_LOCK)
    assert not batch["lock_left"].any() and not batch["lock_right"].any()
    assert batch["trigger"].sum() > 50  # the shared tick still computes the trigger
    for name in ("post_other", "q_left", "omega_left", "trigger", "lock_left", "flags"):
        np.testing.assert_array_equal(batch[name], live[name], err_msg=name)


def test_a_registered_controller_runs_live_in_a_real_worker(
    constant: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The worker is a spawned process: it learns of the module from the environment.
    monkeypatch.setenv(registry.ENV_MODULES, MODULE)
    batches: list[TickBatch] = []
    runs: list[RunStarted] = []
    lock = threading.Lock()

    def on_ticks(b: TickBatch) -> None:
        with lock:
            batches.append(b)

    def count() -> int:
        with lock:
            return sum(len(b.ticks) for b in batches)

    sup = WorkerSupervisor(
        WorkerConfig(device_kind="sim", device_speed=10, device_script="squat-sequence",
                     spec=ControllerSpec.from_config(
                         "constant", {"settings": {"extra": {"constant": 0.125}}})),
        WorkerCallbacks(on_ticks=on_ticks, on_run_started=runs.append))
    sup.start()
    try:
        wait_for(lambda: count() >= 600 or not sup.state.alive, 120,
                 "600 ticks from the worker")
    finally:
        sup.stop()
    assert count() >= 600, f"the worker stopped: {sup.state.errors}"
    assert runs and runs[0].controller == "constant", sup.state.errors
    with lock:
        ticks = np.concatenate([b.ticks for b in batches if b.run_token == runs[0].run_token])
    cols = columns(ticks)
    good = cols["flags"] == 0
    assert good.sum() > 500
    assert np.all(cols["post_other"][good] == 0.125)
    assert np.all(cols["controller_ran"][good]) and not cols["lock_left"].any()
    assert np.all(np.isfinite(cols["omega_left"][good]))
