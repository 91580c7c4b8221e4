"""The worker as a real spawned process: ticks arrive, death is noticed fast, restart works,
and a worker whose server dies stops on its own."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from backend.worker import supervisor as supervisor_module
from backend.worker.messages import RunStarted, TickBatch, WorkerConfig
from backend.worker.supervisor import WorkerBusyError, WorkerCallbacks, WorkerSupervisor
from controller.controllers.spec import ControllerSpec
from tests.faults.served import alive
from tests.polling import wait_for

pytestmark = pytest.mark.slow


class Collected:
    def __init__(self) -> None:
        self.ticks: list[TickBatch] = []
        self.runs: list[RunStarted] = []
        self.exits: list[tuple[int | None, str, float]] = []
        self.got_ticks = threading.Event()
        self.exited = threading.Event()

    def callbacks(self) -> WorkerCallbacks:
        def on_ticks(b: TickBatch) -> None:
            self.ticks.append(b)
            if sum(len(x.records) for x in self.ticks) >= 50:
                self.got_ticks.set()

        def on_exit(code: int | None, reason: str) -> None:
            self.exits.append((code, reason, time.monotonic()))
            self.exited.set()

        return WorkerCallbacks(on_ticks=on_ticks, on_run_started=self.runs.append, on_exit=on_exit)


def test_ticks_arrive_in_order_from_a_real_worker() -> None:
    got = Collected()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim"), got.callbacks())
    sup.start()
    try:
        assert got.got_ticks.wait(60), f"no ticks; errors: {sup.state.errors}"
        records = [r for b in got.ticks for r in b.records]
        seqs = [r.seq for r in records]
        assert seqs == sorted(seqs)
        assert got.runs and got.runs[0].controller == "none"
        # Plausible hip angles, in radians, from the simulated wearer's encoders.
        assert all(-0.6 < r.q_left < 2.2 for r in records)
        # The device's own clock: one sample every 10 ms, none skipped.
        ts = [r.t for r in records]
        assert all(b - a == pytest.approx(0.01) for a, b in zip(ts, ts[1:], strict=False))
        wait_for(lambda: sup.state.status is not None, 30, "the worker's first status report")
        assert sup.state.status is not None and sup.state.status.device.alive
        assert sup.state.status.loop.gaps == 0
    finally:
        sup.stop()
    assert not sup.state.alive


def test_sigkill_is_noticed_and_restart_recovers() -> None:
    # How fast the death is noticed: bench/bench_faults.py (`--only worker`).
    got = Collected()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim"), got.callbacks())
    sup.start()
    try:
        assert got.got_ticks.wait(60)
        pid = sup.state.pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        assert got.exited.wait(30)
        code, reason, _ = got.exits[0]
        assert code == -signal.SIGKILL and "SIGKILL" in reason
        assert not sup.state.alive

        got.got_ticks.clear()
        got.ticks.clear()
        sup.restart()
        assert sup.state.alive and sup.state.pid != pid and sup.state.restarts == 1
        assert got.got_ticks.wait(60)
    finally:
        sup.stop()


ORPHAN_SCRIPT = """
import threading, time
from backend.worker.messages import WorkerConfig
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
if __name__ == "__main__":
    ticked = threading.Event()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim"),
                           WorkerCallbacks(on_ticks=lambda b: ticked.set()))
    sup.start()
    ticked.wait(120)  # the worker runs its loop: only then is its pid printed
    print(sup.state.pid, flush=True)
    time.sleep(600)  # a server that stays up until the test kills it
"""


def test_a_restart_waits_for_the_last_workers_data_to_be_stored(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A database that blocks the storing of ticks (a slow disk, a lock held elsewhere)
    holds the old worker's reader: a restart meanwhile is refused (it would start a
    new worker whose runs mix with the old one's, and skip the old one's exit), and
    goes through once the old data is stored, the old worker's exit recorded first."""
    monkeypatch.setattr(supervisor_module, "READER_WAIT_S", 1.0)
    got = Collected()
    stalled, resume = threading.Event(), threading.Event()
    base = got.callbacks()
    order: list[str] = []

    def storing(b: TickBatch) -> None:
        base.on_ticks(b)
        if got.got_ticks.is_set() and not resume.is_set():
            stalled.set()
            resume.wait(60)  # the database does not answer

    def exited(code: int | None, reason: str) -> None:
        order.append("exit")
        base.on_exit(code, reason)

    def run_started(msg: RunStarted) -> None:
        order.append("run")
        got.runs.append(msg)

    sup = WorkerSupervisor(WorkerConfig(device_kind="sim"),
                           WorkerCallbacks(on_ticks=storing, on_run_started=run_started,
                                           on_exit=exited))
    sup.start()
    try:
        assert stalled.wait(60), "the storing never stalled"
        old_pid = sup.state.pid
        with pytest.raises(WorkerBusyError, match="still being stored"):
            sup.restart()
        assert order == ["run"]  # the old worker's exit waits with its data
        resume.set()
        wait_for(lambda: "exit" in order, 60, "the old worker's data stored")
        sup.restart()
        assert sup.state.alive and sup.state.pid != old_pid
        wait_for(lambda: len(got.runs) >= 2, 60, "the new worker's first run")
        assert order == ["run", "exit", "run"]
    finally:
        resume.set()
        sup.stop()


def test_worker_exits_when_its_server_is_killed(tmp_path: Path) -> None:
    script = tmp_path / "server.py"
    script.write_text(ORPHAN_SCRIPT)
    root = Path(__file__).resolve().parents[3]
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                            cwd=root, env={**os.environ, "PYTHONPATH": str(root)})
    try:
        assert proc.stdout is not None
        worker_pid = int(proc.stdout.readline())  # printed once the worker ticks
        assert alive(worker_pid)
        proc.kill()
        proc.wait(5)
        wait_for(lambda: not alive(worker_pid), 10, "the orphaned worker to exit")
    finally:
        proc.kill()


def test_a_new_simulated_wearer_is_swapped_in_without_a_new_process() -> None:
    got = Collected()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim", device_seed=1, device_speed=20,
                                        device_script="squat-sequence"), got.callbacks())
    sup.start()
    try:
        assert got.got_ticks.wait(60), f"no ticks; errors: {sup.state.errors}"
        wait_for(lambda: any(r.truth_activity == "squat" for b in list(got.ticks)
                             for r in b.records), 60, "the first wearer to squat")
        pid = sup.state.pid
        assert sup.set_simulation(7, "walking")
        wait_for(lambda: any(b.run_token == 2 for b in list(got.ticks)) and len(got.runs) >= 2,
                 30, f"a new run (errors: {sup.state.errors})")
        wait_for(lambda: any(r.truth_activity == "walk" for b in list(got.ticks)
                             if b.run_token == 2 for r in b.records), 60,
                 "the new wearer to walk")
        assert sup.state.pid == pid and sup.state.alive
        assert [r.run_token for r in got.runs] == [1, 2]
        first = [r for b in got.ticks if b.run_token == 1 for r in b.records]
        second = [r for b in got.ticks if b.run_token == 2 for r in b.records]
        # The new wearer's device starts its own sample count and clock.
        assert second[0].seq < first[-1].seq and second[0].t < first[-1].t
        # ... walks, where the first squatted.
        assert "walk" in {r.truth_activity for r in second}
        assert "squat" not in {r.truth_activity for r in second}
        assert "squat" in {r.truth_activity for r in first}
        # Health counts the new run's ticks only.
        st = sup.state.status
        assert st is not None and st.run_token == 2 and st.loop.ticks <= len(second) + 500

        # A script that does not exist is refused; the wearer and run stay.
        errors_before = len(sup.state.errors)
        assert sup.set_simulation(8, "no-such-script")
        wait_for(lambda: len(sup.state.errors) > errors_before, 10,
                 "the bad script to be reported")
        assert "no-such-script" in sup.state.errors[-1]
        n = len(got.ticks)
        wait_for(lambda: len(got.ticks) > n + 5, 30, "ticks after the refusal")
        assert sup.state.alive and len(got.ticks) > n
        assert {b.run_token for b in got.ticks[n:]} == {2}
    finally:
        sup.stop()
    assert not sup.state.alive


def test_a_timed_run_ends_by_itself_after_exactly_its_samples() -> None:
    got = Collected()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim", device_speed=20), got.callbacks())
    sup.start()
    try:
        assert got.got_ticks.wait(60), f"no ticks; errors: {sup.state.errors}"
        sup.set_controller(ControllerSpec("pec"), max_ticks=250)
        wait_for(lambda: len(got.runs) >= 3, 30, f"the timed run to end ({got.runs})")
        wait_for(lambda: sum(len(b.records) for b in list(got.ticks)
                             if b.run_token == got.runs[2].run_token) > 5, 30,
                 "ticks of the run after the timed one")
        assert [r.controller for r in got.runs] == ["none", "pec", "none"]
        timed = [r for b in got.ticks if b.run_token == got.runs[1].run_token
                 for r in b.records]
        assert len(timed) == 250
        seqs = [r.seq for r in timed]
        assert seqs == list(range(seqs[0], seqs[0] + 250))
        after = [r for b in got.ticks if b.run_token == got.runs[2].run_token
                 for r in b.records]
        assert after and after[0].seq == seqs[-1] + 1
        assert not any(r.lock_left or r.lock_right for r in after[5:])
    finally:
        sup.stop()
