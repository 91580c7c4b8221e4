"""Real processes for the safety fault tests: the simulated exoskeleton as its own UDP
device process, the control worker as its own process, and a man-in-the-middle on the
link for the attacks that need one. Everything waits on progress with a deadline."""

from __future__ import annotations

import json
import multiprocessing
import os
import select
import socket
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from backend.worker.messages import RunStarted, TickBatch, WorkerConfig
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.tick_record import TickRecord
from tests import c_device
from tests.backend.worker.unchecked import unchecked_spec
from tests.faults import zygote
from tests.polling import wait_for

ROOT = Path(__file__).resolve().parents[2]


#: A device process: a child of this process (the C device; the Python device outside
#: tests/faults), or the Python device forked from the module's zygote
#: (`tests/faults/zygote.py`).
DeviceProcess = subprocess.Popen[str] | zygote.ZygoteProcess


@contextmanager
def device_process(port: int, key_file: Path, script: str, seed: int = 1,
                   extra: tuple[str, ...] = (), implementation: str = "python",
                   ) -> Iterator[DeviceProcess]:
    """`exostudy device-sim` as a real process on `port`, the Python reference device
    or the C device (same arguments; its simulated wearer on this interpreter);
    stopped (SIGTERM) on exit. In tests/faults the Python device, and the C device's
    simulated wearer (its `--python`), are forked from the module's zygote, which has
    imported them already: the same entry point and arguments as `python -m ...`,
    without an interpreter start (about 1.3 s of CPU) each."""
    args = ["--port", str(port), "--seed", str(seed), "--script", script,
            "--key-file", str(key_file), *extra]
    proc: DeviceProcess
    if implementation != "c" and zygote.active():
        proc = zygote.current().spawn("controller.sim.device_server", args, cwd=ROOT)
    else:
        python = str(zygote.current().launcher) if zygote.active() else sys.executable
        command = ([str(c_device.device_binary()), *args, "--python", python]
                   if implementation == "c"
                   else [sys.executable, "-m", "controller.sim.device_server", *args])
        proc = subprocess.Popen(
            command,
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )
    try:
        yield proc
    finally:
        _stop(proc)


def _stop(proc: DeviceProcess) -> None:
    """SIGTERM, and SIGKILL if it has not ended 15 s later (its pipes read meanwhile)."""
    proc.terminate()
    try:
        proc.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()


@contextmanager
def model_device_process(target: Callable[..., None], *args: Any
                         ) -> Iterator[multiprocessing.process.BaseProcess | zygote.ZygoteProcess]:
    """A device process running `target(*args)` (a module-level function that calls
    `controller.sim.device_server.serve` with a model of its own); killed on exit.
    Forked from the module's zygote in tests/faults, else a fresh (spawned) process."""
    if zygote.active():
        forked = zygote.current().call(target, *args)
        try:
            yield forked
        finally:
            _stop(forked)
        return
    ctx = multiprocessing.get_context("spawn")
    proc = ctx.Process(target=target, args=args, daemon=True)
    proc.start()
    try:
        yield proc
    finally:
        proc.terminate()
        proc.join(10)
        if proc.is_alive():
            proc.kill()
            proc.join(5)


class Worker:
    """The real worker process on a UDP device, with every tick it reports."""

    def __init__(self, port: int, key_file: Path, controller: str = "none",
                 controller_config: dict[str, Any] | None = None) -> None:
        self.records: list[TickRecord] = []
        self.runs: list[RunStarted] = []
        self._lock = threading.Lock()
        # Sent as given, past the server's checks: the worker validates it again.
        config = WorkerConfig(device_kind="udp", device_host="127.0.0.1", device_port=port,
                              device_key_file=str(key_file),
                              spec=unchecked_spec(controller, controller_config),
                              status_interval=0.1)
        self.sup = WorkerSupervisor(config, WorkerCallbacks(on_ticks=self._ticks,
                                                            on_run_started=self._run))

    def _ticks(self, batch: TickBatch) -> None:
        with self._lock:
            self.records.extend(batch.records)

    def _run(self, msg: RunStarted) -> None:
        with self._lock:
            self.runs.append(msg)

    def ticks(self) -> list[TickRecord]:
        """A copy of every tick so far."""
        with self._lock:
            return list(self.records)

    def wait_ticks(self, n: int, timeout: float = 90.0) -> list[TickRecord]:
        """Wait until `n` more ticks than now have arrived; returns those."""
        start = len(self.ticks())
        wait_for(lambda: len(self.ticks()) >= start + n, timeout,
                 f"{n} ticks from the worker (errors: {self.sup.state.errors})")
        return self.ticks()[start : start + n]

    def link_drops(self) -> dict[str, int]:
        """The link's drop counters from the worker's latest status report."""
        st = self.sup.state.status
        return dict(st.device.link_drops) if st is not None else {}

    def __enter__(self) -> Worker:
        self.sup.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.sup.stop("test over")


def locked_ticks(records: list[TickRecord]) -> int:
    """Ticks on which the worker commanded a lock on either side."""
    return sum(r.lock_left or r.lock_right for r in records)


def lock_onsets(records: list[TickRecord]) -> list[int]:
    """Indices of ticks where a lock command starts on either side."""
    return [i for i in range(1, len(records))
            if (records[i].lock_left and not records[i - 1].lock_left)
            or (records[i].lock_right and not records[i - 1].lock_right)]


class Proxy:
    """A man-in-the-middle on the link: the worker talks to `port`, which forwards to
    the device and back, and lets a test inject or record datagrams in either direction
    (an attacker who controls the network, with no key)."""

    def __init__(self, device_port: int) -> None:
        self.device = ("127.0.0.1", device_port)
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # faces the worker
        self.front.bind(("127.0.0.1", 0))
        self.port = int(self.front.getsockname()[1])
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # faces the device
        self.back.bind(("127.0.0.1", 0))
        self.worker: tuple[str, int] | None = None
        self.to_worker: list[bytes] = []  # every datagram the device sent
        self.to_device: list[bytes] = []  # every datagram the worker sent
        #: Decides per worker datagram whether it is held back (True) instead of
        #: forwarded; held ones are kept in `held` (recorded in `to_device` either way).
        self.hold: Callable[[bytes], bool] = lambda d: False
        self.held: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="proxy", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.front, self.back], [], [], 0.05)
            for sock in ready:
                try:
                    data, addr = sock.recvfrom(4096)
                    if sock is self.front:
                        self.worker = (str(addr[0]), int(addr[1]))
                        self.to_device.append(data)
                        if self.hold(data):
                            self.held.append(data)
                        else:
                            self.back.sendto(data, self.device)
                    elif self.worker is not None:
                        self.to_worker.append(data)
                        self.front.sendto(data, self.worker)
                except OSError:
                    continue  # the worker has gone (ICMP port unreachable): keep going

    def send_to_worker(self, data: bytes) -> None:
        """Inject a datagram that the worker sees as coming from the device."""
        assert self.worker is not None
        self.front.sendto(data, self.worker)

    def send_to_device(self, data: bytes) -> None:
        """Inject a datagram that the device sees as coming from the worker's machine."""
        self.back.sendto(data, self.device)

    def __enter__(self) -> Proxy:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2)
        self.front.close()
        self.back.close()


def stop_and_read_stats(proc: Any) -> dict[str, Any]:
    """SIGTERM the device and parse the statistics line it prints."""
    proc.terminate()
    out, err = proc.communicate(timeout=15)
    lines = [line for line in out.splitlines() if line.startswith("{")]
    assert lines, f"no statistics line from the device:\n{out}\n{err}"
    stats: dict[str, Any] = json.loads(lines[-1])
    return stats
