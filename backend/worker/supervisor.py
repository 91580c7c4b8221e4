"""Starts, watches and restarts the worker process from the server.

A reader thread waits on both the worker's pipe and its process sentinel, so a worker
that dies (even by SIGKILL) is noticed within `POLL_S` seconds, after the messages it
had already sent are drained and stored.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import Any

from backend.worker import child_processes
from backend.worker.device_gate import DeviceGate
from backend.worker.messages import (
    BringupCommand,
    BringupResult,
    Calibrate,
    CalibrationResult,
    CommandResult,
    RunStarted,
    SetController,
    SetSimulation,
    StopWorker,
    TickBatch,
    Wearer,
    WorkerConfig,
    WorkerError,
    WorkerStatus,
)
from backend.worker.process import worker_main
from controller.controllers.spec import ControllerSpec

log = logging.getLogger(__name__)

POLL_S = 0.1


@dataclass
class WorkerCallbacks:
    """Where the supervisor delivers what the worker says. Called on the reader thread."""

    on_ticks: Callable[[TickBatch], None] = lambda batch: None
    on_run_started: Callable[[RunStarted], None] = lambda msg: None
    on_exit: Callable[[int | None, str], None] = lambda code, reason: None
    on_event: Callable[[str, dict[str, Any]], None] = lambda kind, data: None
    on_calibration: Callable[[CalibrationResult], None] = lambda result: None
    on_command_result: Callable[[CommandResult], None] = lambda result: None
    on_bringup: Callable[[BringupResult], None] = lambda result: None


@dataclass
class WorkerState:
    """What the server knows about its worker (read by the health endpoint)."""

    alive: bool = False
    pid: int | None = None
    started_at: float | None = None
    exited_at: float | None = None
    exit_code: int | None = None
    exit_reason: str = ""
    restarts: int = 0
    status: WorkerStatus | None = None
    status_at: float | None = None
    errors: list[str] = field(default_factory=list)


#: How long the reader waits for the process to end once its pipe has closed.
EXIT_WAIT_S = 5.0
#: How long a (re)start waits for the last worker's reader to store what it sent.
READER_WAIT_S = 30.0


class WorkerBusyError(RuntimeError):
    """The worker cannot start yet: the last one's data is still being stored."""


class WorkerSupervisor:
    """Owns one worker process at a time."""

    def __init__(self, config: WorkerConfig, callbacks: WorkerCallbacks) -> None:
        self.config = config
        self.callbacks = callbacks
        self.state = WorkerState()
        self._proc: BaseProcess | None = None
        self._out: Connection | None = None
        self._cmd: Connection | None = None
        self._reader: threading.Thread | None = None
        self._lock = threading.RLock()
        self._stopping = False
        self._request_id = 0
        self._bound = False  # the configured spec is bound to a device (`set_controller`)

    @property
    def process(self) -> BaseProcess | None:
        """The current worker process, if one was started."""
        return self._proc

    def start(self) -> None:
        """Start a worker unless one is running. Raises WorkerBusyError while the last
        worker's reader still stores what it sent (its last ticks, its run's end, the
        trial it interrupted): a new worker started beside it would have its runs
        mixed with the old one's."""
        with self._lock:
            if self._proc is not None and self._proc.is_alive():
                return
            reader = self._reader
        if reader is not None and reader is not threading.current_thread():
            # Outside the lock: the reader takes it to record the old worker's exit.
            reader.join(READER_WAIT_S)
            if reader.is_alive():
                raise WorkerBusyError(
                    "the last worker's data is still being stored (the database is slow "
                    f"or locked for more than {READER_WAIT_S:g} s): start it again later")
        with self._lock:
            if self._proc is not None and self._proc.is_alive():
                return
            if self.state.started_at is not None or self._bound:
                # A restarted worker never resumes the controller of a trial that has
                # ended with its predecessor: it begins unlocked, with "none". Nor does
                # a first one start a controller bound to a device that has not proved
                # its identity to it yet.
                self.config = replace(self.config, spec=ControllerSpec("none"))
                self._bound = False
            ctx = child_processes.context()
            out_parent, out_child = ctx.Pipe(duplex=False)
            cmd_child, cmd_parent = ctx.Pipe(duplex=False)
            proc = child_processes.start(
                worker_main, (self.config, out_child, cmd_child, os.getpid()),
                "exostudy-worker")
            out_child.close()
            cmd_child.close()
            if self.state.started_at is not None:
                self.state.restarts += 1
            self._proc, self._out, self._cmd = proc, out_parent, cmd_parent
            self._stopping = False
            self.state.alive = True
            self.state.pid = proc.pid
            self.state.started_at = time.time()
            self.state.exit_code = None
            self.state.exit_reason = ""
            self.state.status = None
            self._reader = threading.Thread(
                target=self._read, args=(proc, out_parent), name="worker-reader", daemon=True
            )
            self._reader.start()
            self.callbacks.on_event("worker", {"alive": True, "pid": proc.pid})

    def stop(self, reason: str = "requested", timeout: float = 3.0) -> None:
        """Ask the worker to release the device and exit; force it if it does not.

        Only the reader thread waits on the process: the fork server reports an exit
        once, on one pipe, and of two threads waiting on it the one that reads second
        records 255 ("unknown") however the worker ended. So this waits on the reader,
        outside the lock its record of the exit takes, and signals the worker only
        while it has not exited."""
        with self._lock:
            proc, cmd, reader = self._proc, self._cmd, self._reader
            if proc is None or reader is None:
                return
            self._stopping = True
            self.state.exit_reason = reason
            if cmd is not None:
                try:
                    cmd.send(StopWorker(reason))
                except (BrokenPipeError, OSError):
                    pass
        reader.join(timeout)
        for force in (proc.terminate, proc.kill):
            if not reader.is_alive() or wait([proc.sentinel], 0):
                break
            force()
            reader.join(1.0)
        reader.join(2.0)

    def restart(self) -> None:
        """Stop (if running) and start again with the same configuration."""
        self.stop("restart")
        self.start()

    def _next_request_id(self) -> int:
        self._request_id += 1
        return self._request_id

    def set_controller(self, spec: ControllerSpec, max_ticks: int | None = None,
                       device: DeviceGate | None = None, wearer: Wearer | None = None) -> int:
        """Switch controller in the running worker; it takes effect at the next tick (and
        ends after `max_ticks` samples, if given); with `device`, only on that device
        (`backend.worker.device_gate`). Returns the request id the worker's
        `CommandResult` will carry, 0 when no worker runs (the specification then
        applies at the next start, unless it is bound to a device: a worker starts
        before its device has proved anything, so then it starts with `none`). With
        `wearer`, the in-process simulator takes that wearer first, at the same sample;
        the configuration records it once the worker's new run reports it (`_follow`),
        so a refused or countermanded start leaves no wearer the worker does not run."""
        with self._lock:
            self.config = replace(self.config, spec=spec)
            if wearer is not None and wearer.speed is None:
                # No speed: the one asked for last, as for `set_simulation`.
                wearer = replace(wearer, speed=self.config.device_speed)
            self._bound = device is not None
            if self._cmd is None or not self.state.alive:
                return 0
            rid = self._next_request_id()
            try:
                self._cmd.send(SetController(spec, max_ticks, rid, device, wearer))
            except (BrokenPipeError, OSError):
                return 0
            return rid

    def set_simulation(self, seed: int, script: str, speed: float | None = None,
                       max_ticks: int | None = None) -> int | None:
        """Ask the running worker to switch its simulated wearer or script (its run ends
        after `max_ticks` samples, if given); returns the request id its `CommandResult`
        will carry, None when no worker runs (the new configuration then applies at the
        next start). A running worker's new wearer is recorded when its run reports it
        (`_follow`): a refused change records nothing."""
        with self._lock:
            speed = self.config.device_speed if speed is None else speed
            if self._cmd is not None and self.state.alive:
                rid = self._next_request_id()
                try:
                    self._cmd.send(SetSimulation(seed, script, speed, rid, max_ticks))
                    return rid
                except (BrokenPipeError, OSError):
                    pass
            self.config = replace(self.config, device_seed=seed, device_script=script,
                                  device_speed=speed)
            return None

    def _follow(self, msg: RunStarted) -> None:
        """The simulated wearer the worker runs and the speed asked for it, as its new
        run reports them: a restart brings back that one, and a wearer put on without a
        speed takes that speed. Never one a refused or countermanded request named."""
        w = msg.wearer
        if w is None or w.speed is None:
            return
        with self._lock:
            self.config = replace(self.config, device_seed=w.seed, device_script=w.script,
                                  device_speed=w.speed)

    def request_calibration(self, seconds: float, max_std_deg: float) -> int:
        """Ask the worker to calibrate over the next `seconds`; returns the request id.
        The result arrives through `callbacks.on_calibration`."""
        with self._lock:
            if self._cmd is None or not self.state.alive:
                raise RuntimeError("the worker is not running")
            rid = self._next_request_id()
            self._cmd.send(Calibrate(seconds, max_std_deg, rid))
            return rid

    def request_bringup(self, cmd: BringupCommand) -> int:
        """Send a hardware bring-up command; returns the request id its
        `BringupResult` (through `callbacks.on_bringup`) will carry."""
        with self._lock:
            if self._cmd is None or not self.state.alive:
                raise RuntimeError("the worker is not running")
            rid = self._next_request_id()
            self._cmd.send(replace(cmd, request_id=rid))
            return rid

    def _read(self, proc: BaseProcess, conn: Connection) -> None:
        while True:
            ready = wait([conn, proc.sentinel], timeout=POLL_S)
            if conn in ready and not self._receive(conn):
                ready = [proc.sentinel]
            if proc.sentinel in ready or (not ready and not proc.is_alive()):
                # Keep what the worker managed to send before it died.
                while True:
                    try:
                        if not conn.poll(0) or not self._receive(conn):
                            break
                    except (EOFError, OSError):
                        break
                # The pipe ends a moment before the process does; on a busy machine
                # that moment can exceed a second, and an exit code read too early is
                # None ("unknown"). A worker that hangs after closing its pipe is
                # killed by `stop`; the device's watchdog has released long before.
                proc.join(EXIT_WAIT_S)
                self._on_exit(proc)
                return

    def _receive(self, conn: Connection) -> bool:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return False
        try:
            if isinstance(msg, TickBatch):
                self.callbacks.on_ticks(msg)
            elif isinstance(msg, WorkerStatus):
                self.state.status = msg
                self.state.status_at = time.time()
            elif isinstance(msg, RunStarted):
                self._follow(msg)
                self.callbacks.on_run_started(msg)
            elif isinstance(msg, CalibrationResult):
                self.callbacks.on_calibration(msg)
            elif isinstance(msg, CommandResult):
                self.callbacks.on_command_result(msg)
            elif isinstance(msg, BringupResult):
                self.callbacks.on_bringup(msg)
            elif isinstance(msg, WorkerError):
                self.state.errors = [*self.state.errors[-19:], msg.message]
                log.warning("worker: %s", msg.message)
                self.callbacks.on_event("error", {"message": msg.message, "fatal": msg.fatal})
        except Exception:
            log.exception("handling a worker message failed")
        return True

    def _on_exit(self, proc: BaseProcess) -> None:
        code = proc.exitcode
        # `stop` may be joining the same process from its own thread: whichever thread's
        # waitpid loses the race gets ECHILD, and multiprocessing then reports None until
        # the winner has stored the code, a moment later. Ask again briefly.
        deadline = time.monotonic() + 1.0
        while code is None and time.monotonic() < deadline:
            time.sleep(0.01)
            code = proc.exitcode
        with self._lock:
            if proc is not self._proc:
                return
            self.state.alive = False
            self.state.exited_at = time.time()
            self.state.exit_code = code
            if not self._stopping:
                self.state.exit_reason = _describe_exit(code)
                level = logging.INFO if code == 0 else logging.ERROR
                log.log(level, "worker exited without being asked: %s", self.state.exit_reason)
            reason = self.state.exit_reason
        self.callbacks.on_exit(code, reason)
        self.callbacks.on_event("worker", {"alive": False, "exit_code": code, "reason": reason})


def _describe_exit(code: int | None) -> str:
    if code is None:
        return "unknown"
    if code < 0:
        import signal

        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return {
        0: "exited",
        3: "device failed to open",
        4: "lost the server",
        5: "loop failed",
    }.get(code, f"exit code {code}")
