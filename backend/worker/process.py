"""The worker process: the 100 Hz control loop, isolated from the web server.

It runs in its own process (forked from the server's fork server,
`backend.worker.child_processes`) so that nothing the server or a
browser does (garbage collection, a slow request, the GIL) can delay a lock decision.
Safety rules:
- any exit path releases the device (no solenoid stays energised);
- if the server disappears (parent gone or pipe broken) the worker releases and exits;
- ticks are handed to a sender thread through a bounded buffer (`backend.worker.outbox`),
  so a server that reads slowly costs memory up to a limit, then drops (and counts)
  records, never time.
What the worker does with each command, in each state, is `backend.worker.machine`.
"""

from __future__ import annotations

import signal
from multiprocessing.connection import Connection
from types import FrameType

from backend.worker.child_processes import ParentWatch
from backend.worker.devices import make_device
from backend.worker.machine import BACKLOG_HOLD, BACKLOG_RESUME, Machine, let_go
from backend.worker.messages import WorkerConfig, WorkerError
from backend.worker.outbox import OUTBOX_LIMIT, Outbox
from backend.worker.scheduling import raise_priority
from controller.stop_flag import SignalSafeFlag

__all__ = ["BACKLOG_HOLD", "BACKLOG_RESUME", "OUTBOX_LIMIT", "worker_main"]


def worker_main(
    config: WorkerConfig, out_conn: Connection, cmd_conn: Connection, parent_pid: int
) -> None:
    """Entry point of the worker process: open the device, build the state machine
    (`backend.worker.machine`), run its loop; release on every way out."""
    stopping = SignalSafeFlag()  # set by the signal handler below: no lock
    parent = ParentWatch(parent_pid)

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stopping.set()

    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)

    outbox = Outbox(out_conn)
    outbox.thread.start()
    raise_priority()
    try:
        device = make_device(config, parent_pid)
        device.open()
    except Exception as exc:
        outbox.put(WorkerError(f"device {config.device_kind!r} failed to open: {exc}", fatal=True))
        outbox.stop.set()
        outbox.thread.join(1.0)
        raise SystemExit(3) from exc

    exit_code = 0
    machine: Machine | None = None
    try:
        machine = Machine(config, device, outbox, cmd_conn, parent, stopping)
        machine.run()
        exit_code = machine.exit_code
    except Exception as exc:
        outbox.put(WorkerError(f"worker loop failed: {exc!r}", fatal=True))
        exit_code = 5
    finally:
        if machine is not None:
            machine.stop()  # through RELEASING; lets go of the device it holds now
        else:
            let_go(device)
        outbox.stop.set()
        outbox.thread.join(2.0)
    if exit_code:
        raise SystemExit(exit_code)
