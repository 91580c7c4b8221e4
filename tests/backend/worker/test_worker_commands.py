"""Every command to a real worker process is answered (done, or refused with the reason),
and a sped-up simulation is paced by its consumer instead of dropping ticks."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest

from backend.worker.messages import (
    CalibrationResult,
    CommandResult,
    RunStarted,
    TickBatch,
    WorkerConfig,
)
from backend.worker.process import BACKLOG_HOLD
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.controllers.spec import ControllerSpec
from tests.backend.worker.unchecked import unchecked_spec
from tests.polling import wait_for

pytestmark = pytest.mark.slow


class Answers:
    def __init__(self, slow_s_per_record: float = 0.0) -> None:
        self.results: dict[int, CommandResult] = {}
        self.calibrations: dict[int, CalibrationResult] = {}
        self.runs: list[RunStarted] = []
        self.received = 0
        self.seqs: list[int] = []
        self.slow = slow_s_per_record
        self.changed = threading.Condition()

    def callbacks(self) -> WorkerCallbacks:
        def on_ticks(b: TickBatch) -> None:
            self.received += len(b.records)
            self.seqs += [r.seq for r in b.records if b.run_token == 1]
            if self.slow:
                time.sleep(self.slow * len(b.records))  # a slow consumer (database)

        def note(store: Callable[[], None]) -> None:
            with self.changed:
                store()
                self.changed.notify_all()

        return WorkerCallbacks(
            on_ticks=on_ticks,
            on_run_started=lambda m: note(lambda: self.runs.append(m)),
            on_command_result=lambda m: note(lambda: self.results.__setitem__(m.request_id, m)),
            on_calibration=lambda m: note(
                lambda: self.calibrations.__setitem__(m.request_id, m)))

    def wait(self, what: Callable[[], bool], limit_s: float = 120.0) -> None:
        deadline = time.monotonic() + limit_s
        with self.changed:
            while not what():
                left = deadline - time.monotonic()
                assert left > 0, "no answer from the worker"
                self.changed.wait(min(left, 0.5))


def test_commands_are_answered_with_their_run_or_their_reason() -> None:
    got = Answers()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim", device_speed=10,
                                        device_script="squat-sequence"), got.callbacks())
    sup.start()
    try:
        rid = sup.set_controller(ControllerSpec("pec"))
        got.wait(lambda: rid in got.results)
        ok = got.results[rid]
        assert ok.ok and ok.message == ""
        assert [r.controller for r in got.runs if r.run_token == ok.run_token] == ["pec"]

        # No models (sent past the server's checks): refused, and nothing locks.
        rid = sup.set_controller(unchecked_spec("umc"))
        got.wait(lambda: rid in got.results)
        bad = got.results[rid]
        assert not bad.ok and "umc" in bad.message and "models" in bad.message
        assert [r.controller for r in got.runs if r.run_token == bad.run_token] == ["none"]

        srid = sup.set_simulation(3, "no-such-script")
        assert srid is not None
        got.wait(lambda: srid in got.results)
        assert not got.results[srid].ok and "no-such-script" in got.results[srid].message

        # A calibration cut short by a new wearer is answered, with the reason.
        crid = sup.request_calibration(30.0, 1.0)
        srid = sup.set_simulation(4, "walking")
        assert srid is not None
        got.wait(lambda: crid in got.calibrations and srid in got.results)
        assert not got.calibrations[crid].ok
        assert "abandoned" in got.calibrations[crid].message
        assert got.results[srid].ok
    finally:
        sup.stop()


def test_a_sped_up_simulation_waits_for_a_slow_consumer_and_drops_nothing() -> None:
    # The consumer takes 0.4 ms per tick (2,500 ticks/s); the device is asked for
    # 10,000 ticks/s. Without pacing the worker would run 4x ahead and drop ticks.
    got = Answers(slow_s_per_record=0.0004)
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim", device_speed=100,
                                        device_script="squat-sequence"), got.callbacks())
    sup.start()
    try:
        wait_for(lambda: got.received >= 8000 or not sup.state.alive, 120, "8,000 ticks")
        assert sup.state.alive
        st = sup.state.status
        assert st is not None
        assert st.loop.dropped_records == 0
        # The worker is never far ahead of what was consumed: the pause threshold plus
        # what the pipe and one status interval hold.
        assert st.loop.ticks - got.received < BACKLOG_HOLD + 2500
        assert got.seqs == list(range(len(got.seqs)))  # no sample lost or repeated
    finally:
        sup.stop()
