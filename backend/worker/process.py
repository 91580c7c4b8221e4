"""The worker process: the 100 Hz control loop, isolated from the web server.

It runs in its own process (multiprocessing, spawn) so that nothing the server or a
browser does (garbage collection, a slow request, the GIL) can delay a lock decision.
Safety rules:
- any exit path releases the device (no solenoid stays energised);
- if the server disappears (parent gone or pipe broken) the worker releases and exits;
- ticks are handed to a sender thread through a bounded buffer, so a server that reads
  slowly costs memory up to a limit, then drops (and counts) records, never time.
"""

from __future__ import annotations

import collections
import dataclasses
import gc
import math
import os
import resource
import signal
import threading
import time
from dataclasses import replace
from multiprocessing.connection import Connection
from types import FrameType
from typing import Any

import numpy as np

from backend.schemas.live import DeviceReport, LoopReport
from backend.worker import bringup
from backend.worker.devices import make_device
from backend.worker.messages import (
    BringupCapture,
    BringupPulse,
    BringupWatchdog,
    Calibrate,
    CalibrationResult,
    CommandResult,
    RunStarted,
    SetController,
    SetSimulation,
    StopWorker,
    TickBatch,
    WorkerConfig,
    WorkerError,
    WorkerMessage,
    WorkerStatus,
)
from controller.calibration import CalibrationError, calibrate
from controller.device.base import SAMPLE_PERIOD_S, Device
from controller.factory import load_models, make_controller, make_from_spec
from controller.loop import ControlLoop
from controller.spec import ControllerSpec
from controller.stop_flag import SignalSafeFlag
from controller.tick import TickRecord

#: Records kept for the server if it stops reading: one minute at 100 Hz.
OUTBOX_LIMIT = 6000
BATCH_INTERVAL_S = 0.02
#: A sped-up simulation (device time is virtual) waits while more records than this are
#: queued for the server, and resumes below `BACKLOG_RESUME`: the worker never produces
#: faster than the server stores, so nothing is dropped and a command's answer is never
#: stuck behind seconds of queued ticks on a loaded machine. 1,000 records are 0.125 s
#: of an 80x simulation; a real-time device never waits (it cannot).
BACKLOG_HOLD = 1000
BACKLOG_RESUME = 250


class _Outbox:
    """Hands records from the loop to the pipe on a separate thread, packed into one
    block per batch (`TickBatch`). The loop thread only appends a record; packing and
    pickling happen on this thread, outside the lock the loop takes."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.records: list[TickRecord] = []
        # Control messages, and the records queued before each of them as
        # (run token, records) still to be packed, in the order they must go out.
        self.messages: collections.deque[WorkerMessage | tuple[int, list[TickRecord]]] = (
            collections.deque())
        self.dropped = 0
        self.broken = threading.Event()
        self.stop = threading.Event()
        self.run_token = 0
        self._unsent = 0  # records put and not yet written to the pipe
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, name="worker-outbox", daemon=True)

    def put_record(self, record: TickRecord) -> None:
        with self._lock:
            if len(self.records) >= OUTBOX_LIMIT:
                del self.records[0]
                self.dropped += 1
            else:
                self._unsent += 1
            self.records.append(record)

    def backlog(self) -> int:
        """Records waiting for the server (queued here or being written)."""
        with self._lock:
            return self._unsent

    def put(self, message: WorkerMessage) -> None:
        # Control messages go out after the records queued before them, so a RunStarted
        # is never overtaken by ticks of the run it announces (flush first).
        with self._lock:
            if self.records:
                self.messages.append((self.run_token, self.records))
                self.records = []
            self.messages.append(message)

    def _drain(self) -> list[WorkerMessage]:
        with self._lock:
            taken = list(self.messages)
            self.messages.clear()
            if self.records:
                taken.append((self.run_token, self.records))
                self.records = []
        return [TickBatch.from_records(*m) if isinstance(m, tuple) else m for m in taken]

    def _run(self) -> None:
        while not self.stop.is_set():
            self.flush()
            self.stop.wait(BATCH_INTERVAL_S)
        self.flush()

    def flush(self) -> None:
        if self.broken.is_set():
            return
        for msg in self._drain():
            try:
                self.conn.send(msg)
            except (BrokenPipeError, EOFError, OSError):
                self.broken.set()
                return
            if isinstance(msg, TickBatch):
                with self._lock:
                    self._unsent -= len(msg)


class _Runs:
    """The worker's current run, and the one way a new one starts.

    A run is what the server stores ticks under: every change of controller, wearer or
    configuration starts one, announced by `RunStarted` before any of its ticks (the
    outbox sends the ticks queued before it under the old token first)."""

    def __init__(self, outbox: _Outbox, pid: int) -> None:
        self.outbox, self.pid = outbox, pid
        self.token = 0
        self.config: dict[str, Any] = {}
        self.ticks = 0  # samples of the current run
        self.limit: int | None = None  # a timed run ends by itself after this many

    def start(self, controller: str, config: dict[str, Any], device_kind: str,
              limit: int | None = None, *, count_again: bool = True) -> int:
        """Announce a new run of `controller` with `config`; its token. With
        `count_again=False` the sample count and limit carry over (a calibration
        applied to the running controller)."""
        self.token += 1
        self.config = dict(config)
        if count_again:
            self.ticks, self.limit = 0, limit
        self.outbox.put(RunStarted(self.token, controller, self.config, device_kind,
                                   self.pid))
        self.outbox.run_token = self.token
        return self.token


def worker_main(
    config: WorkerConfig, out_conn: Connection, cmd_conn: Connection, parent_pid: int
) -> None:
    """Entry point of the worker process."""
    stopping = SignalSafeFlag()  # set by the signal handler below: no lock

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stopping.set()

    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)

    outbox = _Outbox(out_conn)
    outbox.thread.start()
    pid = os.getpid()
    _raise_priority()
    try:
        device = make_device(config)
        device.open()
    except Exception as exc:
        outbox.put(WorkerError(f"device {config.device_kind!r} failed to open: {exc}", fatal=True))
        outbox.stop.set()
        outbox.thread.join(1.0)
        raise SystemExit(3) from exc

    exit_code = 0
    try:
        try:
            controller = make_controller(config.controller, config.controller_config)
        except Exception as exc:
            outbox.put(WorkerError(f"controller {config.controller!r}: {exc}; using 'none'"))
            controller = make_controller("none")
        controller.warm_up()
        # Everything allocated so far lives for the whole run: keep the collector from
        # scanning it on every cycle (fewer, shorter pauses inside ticks).
        gc.collect()
        gc.freeze()
        loop = ControlLoop(device, controller)
        calibration: _CalibrationJob | None = None
        runs = _Runs(outbox, pid)
        runs.start(controller.name, config.controller_config, device.kind)
        next_status = time.monotonic()
        held = False  # a sped-up simulation waiting for the server (see `_hold`)
        silent = False  # no sample within the last read's timeout (see below)
        _loop_scheduling(_paced(config))
        while not stopping.is_set():
            if os.getppid() != parent_pid or outbox.broken.is_set():
                exit_code = 4  # the server is gone: release and leave
                break
            commands = cmd_conn.poll()
            if commands:
                _loop_scheduling(False)  # building a controller is no real-time work
            while commands and cmd_conn.poll():
                try:
                    cmd = cmd_conn.recv()
                except (EOFError, OSError):
                    stopping.set()
                    break
                if isinstance(cmd, StopWorker):
                    stopping.set()
                elif isinstance(cmd, SetController):
                    rid, refused = cmd.request_id, ""
                    try:
                        new = make_controller(cmd.name, cmd.config)
                        new.warm_up()
                    except Exception as exc:
                        # A configuration that does not validate is refused, and the
                        # controller it was meant to replace stops too: no locks until
                        # the experimenter sends one that does (safety over continuity).
                        refused = f"controller {cmd.name!r} rejected: {exc}; running 'none'"
                        outbox.put(WorkerError(refused))
                        if loop.controller.name == "none":
                            _answer(outbox, rid, refused)
                            continue
                        new = make_controller("none")
                        cmd = SetController("none", {})
                    loop.controller = new
                    token = runs.start(new.name, cmd.config, device.kind, cmd.max_ticks)
                    _answer(outbox, rid, refused, token)
                elif isinstance(cmd, Calibrate):
                    calibration = _CalibrationJob(cmd, config, runs.config)
                elif isinstance(cmd, BringupCapture | BringupPulse | BringupWatchdog):
                    # The step owns the device for its few seconds (the loop pauses;
                    # the step answers samples itself) and always releases after it.
                    outbox.put(bringup.handle(cmd, device, loop.controller.name))
                    _abandon(outbox, calibration, "a hardware bring-up step ran")
                    calibration = None
                    loop = ControlLoop(device, loop.controller)  # fresh timing after it
                elif isinstance(cmd, SetSimulation):
                    if config.device_kind != "sim":
                        refused = ("the device is not the in-process simulator: there is no "
                                   "simulation to change")
                        outbox.put(WorkerError(refused))
                        _answer(outbox, cmd.request_id, refused)
                        continue
                    sim_config = replace(config, device_seed=cmd.seed, device_script=cmd.script,
                                         device_speed=cmd.speed or config.device_speed)
                    try:
                        new_device = make_device(sim_config)
                        fresh = make_controller(loop.controller.name, runs.config)
                        fresh.warm_up()
                    except Exception as exc:
                        refused = f"simulation seed {cmd.seed}, script {cmd.script!r} " \
                                  f"rejected: {exc}"
                        outbox.put(WorkerError(refused))
                        _answer(outbox, cmd.request_id, refused)
                        continue
                    # Unlocked-safe between wearers: the old device lets go before the
                    # new one opens (a failure to open ends the worker, released).
                    device.release()
                    device.close()
                    device = new_device
                    device.open()
                    config = sim_config
                    _abandon(outbox, calibration, "the simulated wearer changed")
                    calibration = None
                    # Fresh timing too: health counts ticks from the new wearer's start.
                    loop = ControlLoop(device, fresh)
                    next_status = 0.0  # report the new wearer at its first sample
                    token = runs.start(fresh.name, runs.config, device.kind)
                    _answer(outbox, cmd.request_id, "", token)
            if commands:
                _loop_scheduling(_paced(config))
            if stopping.is_set():
                break
            held = _hold(device, outbox, held)
            record = None if held else loop.tick(timeout=0.05)
            if record is None and not held and not silent and device.kind == "udp":
                # 50 ms (5 samples) without a sample: send the release now instead of
                # leaving a held lock to the device's 100 ms watchdog; a device that
                # stopped talking may still be listening. Once per silence.
                device.release()
            silent = record is None and not held
            if record is not None:
                outbox.put_record(record)
                runs.ticks += 1
                if runs.limit is not None and runs.ticks >= runs.limit:
                    # A timed run is over: back to no controller (no locks), a new run.
                    loop.controller = make_controller("none")
                    _abandon(outbox, calibration, "the timed trial ended")
                    calibration = None
                    runs.start("none", {}, device.kind)
                    record = None
                if record is not None and calibration is not None and calibration.add(record):
                    result, offsets = calibration.finish(loop.controller.name)
                    calibration = None
                    outbox.put(result)
                    if offsets is not None:
                        # The running E-UMC takes its calibration at once: a new run.
                        try:
                            spec = ControllerSpec.from_config(loop.controller.name,
                                                              runs.config)
                            spec = replace(spec, settings=replace(spec.settings,
                                                                  calibration=offsets))
                            new = make_from_spec(spec)
                            new.warm_up()
                            loop.controller = new
                            runs.start(new.name, spec.to_config(), device.kind,
                                       count_again=False)
                        except Exception as exc:
                            outbox.put(WorkerError(f"applying the calibration failed: {exc}"))
            now = time.monotonic()
            if now >= next_status:
                next_status = now + config.status_interval
                outbox.put(_status(loop, outbox, pid, runs.token, device.kind,
                                   device.faults()))
    except Exception as exc:
        outbox.put(WorkerError(f"worker loop failed: {exc!r}", fatal=True))
        exit_code = 5
    finally:
        device.release()
        try:
            device.close()
        except Exception:
            pass
        outbox.stop.set()
        outbox.thread.join(2.0)
    if exit_code:
        raise SystemExit(exit_code)


def _hold(device: Device, outbox: _Outbox, held: bool) -> bool:
    """Whether a sped-up simulated device should wait for the server to catch up.

    Only a simulation faster than real time waits (its device time is virtual, so
    waiting changes nothing in the data); it restarts its clock when it resumes, so
    the samples it skipped are not delivered in one burst.
    """
    # Duck-typed: a UDP worker does not import the simulator for this.
    resync = getattr(device, "resync", None)
    if resync is None or float(getattr(device, "speed", 1.0)) <= 1.0:
        return False
    if outbox.backlog() > (BACKLOG_RESUME if held else BACKLOG_HOLD):
        time.sleep(0.002)
        return True
    if held:
        resync()
    return False


def _answer(outbox: _Outbox, request_id: int, refused: str, run_token: int = 0) -> None:
    """Answer a command the server waits for (request id 0: nobody waits)."""
    if request_id:
        outbox.put(CommandResult(request_id, not refused, refused, run_token))


def _abandon(outbox: _Outbox, job: _CalibrationJob | None, why: str) -> None:
    """A calibration cut short still gets its answer, with the reason."""
    if job is not None:
        outbox.put(CalibrationResult(job.cmd.request_id, False,
                                     f"calibration abandoned: {why}", samples=len(job.q)))


def _raise_priority() -> None:
    """Ask the scheduler to prefer the control loop over browsers and the web server.
    Needs privileges (root or CAP_SYS_NICE); without them the loop runs at normal
    priority, which the benchmarks show is enough on an idle machine."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -10)
    except (PermissionError, OSError):
        pass


#: Real-time priority of the loop thread (SCHED_FIFO, low in the 1..99 range: above
#: every ordinary process, below the kernel's own real-time threads).
LOOP_RT_PRIORITY = 10
#: A real-time thread that computes this long without sleeping is a runaway; the kernel
#: signals it (SIGXCPU) and the loop drops back to normal scheduling. A tick computes
#: in well under a millisecond and then sleeps until the next sample.
RT_RUNAWAY_US = 200_000


def _paced(config: WorkerConfig) -> bool:
    """Whether the device's clock paces the loop (hardware, or real-time simulation)."""
    return config.device_kind != "sim" or config.device_speed <= 1.0


def _loop_scheduling(device_paced: bool) -> None:
    """Real-time scheduling for the loop thread while it follows a device's clock.

    Nice -10 is a weight, not a guarantee: with both cores busy (benchmark
    `bench/bench_loop_load.py`) the woken loop still waits behind ordinary processes
    for milliseconds. SCHED_FIFO runs it as soon as its sample is due. Only for a
    device that paces the loop (hardware, or the simulator at real-time speed): a
    sped-up simulation runs flat out and must share the CPU with the server it feeds,
    so it gets normal scheduling. Needs root or CAP_SYS_NICE, else nothing changes.
    """
    try:
        if device_paced:
            signal.signal(signal.SIGXCPU, _drop_realtime)
            resource.setrlimit(resource.RLIMIT_RTTIME, (RT_RUNAWAY_US, RT_RUNAWAY_US * 10))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(LOOP_RT_PRIORITY))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (PermissionError, OSError, ValueError):
        pass


def _drop_realtime(_signum: int, _frame: FrameType | None) -> None:
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except OSError:
        pass


class _CalibrationJob:
    """Collects raw hip angles of the next `seconds` of ticks, then calibrates."""

    def __init__(self, cmd: Calibrate, worker: WorkerConfig, current: dict[str, Any]) -> None:
        self.cmd = cmd
        self.worker = worker
        self.current = current
        self.needed = max(10, round(cmd.seconds / SAMPLE_PERIOD_S))
        self.q: list[tuple[float, float]] = []

    def add(self, r: TickRecord) -> bool:
        """Take one tick; True when enough have been collected."""
        self.q.append((r.q_raw_left, r.q_raw_right))
        return len(self.q) >= self.needed

    def finish(self, running: str
               ) -> tuple[CalibrationResult, tuple[float, float] | None]:
        """The result, and the offsets a running E-UMC takes at once (None otherwise)."""
        rid = self.cmd.request_id
        q = np.asarray(self.q, dtype=np.float64)
        try:
            # The running controller's models, else the worker's default model set.
            spec = ControllerSpec.from_config(running, self.current)
            if spec.models is None and not spec.models_path:
                spec = ControllerSpec("none", models_path=self.worker.models_path)
            mset = load_models(spec)
            start = np.mean([m.mean[0] for m in mset.ordered()], axis=0)
            cal = calibrate(q, start, max_std=math.radians(self.cmd.max_std_deg))
        except (CalibrationError, ValueError) as exc:
            std = np.nanstd(q, axis=0) if q.size else np.array([math.nan, math.nan])
            return CalibrationResult(rid, False, str(exc), std_left_deg=math.degrees(std[0]),
                                     std_right_deg=math.degrees(std[1]), samples=len(q)), None
        std = q.std(axis=0)
        result = CalibrationResult(
            rid, True, "calibrated", cal.offset_left, cal.offset_right,
            math.degrees(std[0]), math.degrees(std[1]), len(q),
        )
        return result, (cal.offset_left, cal.offset_right) if running == "eumc" else None


def _status(
    loop: ControlLoop, outbox: _Outbox, pid: int, run_token: int, kind: str, faults: list[str]
) -> WorkerStatus:
    last = loop.last_sample_at
    age = time.monotonic() - last if last is not None else math.inf
    return WorkerStatus(
        pid=pid,
        run_token=run_token,
        device_kind=kind,
        loop=LoopReport(controller=loop.controller.name, dropped_records=outbox.dropped,
                        **dataclasses.asdict(loop.timing.summary())),
        device=DeviceReport(alive=age < 0.5, last_sample_age_s=age, faults=faults,
                            implausible_samples=loop.implausible,
                            link_drops=loop.device.link_counters()),
    )
