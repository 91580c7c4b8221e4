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
import os
import signal
import threading
import time
from multiprocessing.connection import Connection
from types import FrameType

from controller.factory import make_controller
from controller.loop import ControlLoop
from controller.tick import TickRecord
from backend.worker.devices import make_device
from backend.worker.messages import (
    RunStarted,
    SetController,
    StopWorker,
    TickBatch,
    WorkerConfig,
    WorkerError,
    WorkerMessage,
    WorkerStatus,
)

#: Records kept for the server if it stops reading: one minute at 100 Hz.
OUTBOX_LIMIT = 6000
BATCH_INTERVAL_S = 0.02


class _Outbox:
    """Hands records from the loop to the pipe on a separate thread."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.records: collections.deque[TickRecord] = collections.deque()
        self.messages: collections.deque[WorkerMessage] = collections.deque()
        self.dropped = 0
        self.broken = threading.Event()
        self.stop = threading.Event()
        self.run_token = 0
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, name="worker-outbox", daemon=True)

    def put_record(self, record: TickRecord) -> None:
        with self._lock:
            if len(self.records) >= OUTBOX_LIMIT:
                self.records.popleft()
                self.dropped += 1
            self.records.append(record)

    def put(self, message: WorkerMessage) -> None:
        # Control messages go out after the records queued before them, so a RunStarted
        # is never overtaken by ticks of the run it announces (flush first).
        with self._lock:
            if self.records:
                self.messages.append(TickBatch(self.run_token, tuple(self.records)))
                self.records.clear()
            self.messages.append(message)

    def _drain(self) -> list[WorkerMessage]:
        with self._lock:
            out: list[WorkerMessage] = list(self.messages)
            self.messages.clear()
            if self.records:
                out.append(TickBatch(self.run_token, tuple(self.records)))
                self.records.clear()
        return out

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


def worker_main(
    config: WorkerConfig, out_conn: Connection, cmd_conn: Connection, parent_pid: int
) -> None:
    """Entry point of the worker process."""
    stopping = threading.Event()

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stopping.set()

    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)

    outbox = _Outbox(out_conn)
    outbox.thread.start()
    pid = os.getpid()
    try:
        device = make_device(config)
        device.open()
    except Exception as exc:  # noqa: BLE001 - reported to the server, then exit
        outbox.put(WorkerError(f"device {config.device_kind!r} failed to open: {exc}", fatal=True))
        outbox.stop.set()
        outbox.thread.join(1.0)
        raise SystemExit(3) from exc

    exit_code = 0
    try:
        try:
            controller = make_controller(config.controller, config.controller_config)
        except Exception as exc:  # noqa: BLE001
            outbox.put(WorkerError(f"controller {config.controller!r}: {exc}; using 'none'"))
            controller = make_controller("none")
        controller.warm_up()
        loop = ControlLoop(device, controller)
        run_token = 1
        outbox.run_token = run_token
        outbox.put(RunStarted(run_token, controller.name, dict(config.controller_config),
                              device.kind, pid))
        next_status = time.monotonic()
        while not stopping.is_set():
            if os.getppid() != parent_pid or outbox.broken.is_set():
                exit_code = 4  # the server is gone: release and leave
                break
            while cmd_conn.poll():
                try:
                    cmd = cmd_conn.recv()
                except (EOFError, OSError):
                    stopping.set()
                    break
                if isinstance(cmd, StopWorker):
                    stopping.set()
                elif isinstance(cmd, SetController):
                    try:
                        new = make_controller(cmd.name, cmd.config)
                        new.warm_up()
                    except Exception as exc:  # noqa: BLE001
                        outbox.put(WorkerError(f"controller {cmd.name!r} rejected: {exc}"))
                        continue
                    loop.controller = new
                    run_token += 1
                    outbox.put(RunStarted(run_token, new.name, dict(cmd.config), device.kind, pid))
                    outbox.run_token = run_token
            if stopping.is_set():
                break
            record = loop.tick(timeout=0.05)
            if record is not None:
                outbox.put_record(record)
            now = time.monotonic()
            if now >= next_status:
                next_status = now + config.status_interval
                outbox.put(_status(loop, outbox, pid, run_token, device.kind, device.faults()))
    except Exception as exc:  # noqa: BLE001 - any failure: make safe, report, exit non-zero
        outbox.put(WorkerError(f"worker loop failed: {exc!r}", fatal=True))
        exit_code = 5
    finally:
        device.release()
        try:
            device.close()
        except Exception:  # noqa: BLE001, S110 - closing must not mask the exit
            pass
        outbox.stop.set()
        outbox.thread.join(2.0)
    if exit_code:
        raise SystemExit(exit_code)


def _status(
    loop: ControlLoop, outbox: _Outbox, pid: int, run_token: int, kind: str, faults: list[str]
) -> WorkerStatus:
    s = loop.timing.summary()
    age = time.monotonic() - loop.last_sample_at if loop.last_sample_at is not None else float("inf")
    return WorkerStatus(
        pid=pid,
        run_token=run_token,
        controller=loop.controller.name,
        ticks=s.ticks,
        period_mean_ms=s.period_mean_ms,
        jitter_p50_ms=s.jitter_p50_ms,
        jitter_p99_ms=s.jitter_p99_ms,
        jitter_max_ms=s.jitter_max_ms,
        compute_p50_us=s.compute_p50_us,
        compute_p99_us=s.compute_p99_us,
        overruns=s.overruns,
        gaps=s.gaps,
        timeouts=s.timeouts,
        dropped_records=outbox.dropped,
        device_kind=kind,
        device_alive=age < 0.5,
        last_sample_age_s=age,
        device_faults=tuple(faults),
    )
