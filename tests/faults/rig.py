"""A rig for faults between the worker and the device: the simulated exoskeleton served
over UDP in a thread, a real worker process, and a relay between them that can go
silent in one direction. The device's model records the solenoid command it applies at
every sample, so the moment the watchdog releases is read off the device itself.

With `implementation="c"` the device is the C firmware core (firmware/build/
exostudy-device) as its own process; what it applies at each sample is then read off
its samples by the relay (the SOLENOID_* status bits, which the device sets from what
it drives), whether or not the relay forwards them.

Used by tests/faults/test_watchdog_faults.py and bench/bench_faults.py.
"""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from backend.worker.messages import WorkerConfig
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.config import ControllerConfig
from controller.controllers.spec import ControllerSpec
from controller.device.auth import load_or_create_key
from controller.device.base import LockCommand, Sample
from controller.sim.device_server import serve
from controller.sim.exoskeleton import SimulatedExoskeleton
from tests import c_device
from tests.polling import free_udp_port, wait_for


class RecordingModel:
    """The simulated exoskeleton, recording (monotonic time, left, right) of the
    command the device applied at each sample."""

    def __init__(self, inner: SimulatedExoskeleton) -> None:
        self.inner = inner
        self.dt = inner.dt
        self.applied: list[tuple[float, bool, bool]] = []

    @property
    def finished(self) -> bool:
        return bool(self.inner.finished)

    def warm_up(self) -> None:
        hook = getattr(self.inner, "warm_up", None)
        if callable(hook):
            hook()

    def tick(self, command: LockCommand | None) -> Sample:
        locks = (bool(command.lock_left), bool(command.lock_right)) if command else (False, False)
        self.applied.append((time.monotonic(), *locks))
        return self.inner.tick(command)


class WireRecord:
    """For a device in another process: (monotonic time received, left, right) of the
    solenoid state each of its samples reports, as the relay receives them."""

    def __init__(self) -> None:
        self.applied: list[tuple[float, bool, bool]] = []

    def datagram(self, data: bytes, at: float) -> None:
        """A datagram from the device: a SAMPLE's status word is at bytes 20..23."""
        if len(data) >= 24 and data[:2] == b"EX" and data[3] == 1:
            status = int.from_bytes(data[20:24], "little")
            self.applied.append((at, bool(status & 1), bool(status & 2)))


class Relay:
    """UDP between the worker (which sends to `port`) and the device; `mute_device`
    drops the device's samples (the device goes silent for the host), `mute_host` the
    host's commands. Forward times are kept: `last_sample_at`, `last_command_at`."""

    def __init__(self, device_port: int,
                 on_device: Callable[[bytes, float], None] | None = None) -> None:
        self.on_device = on_device  # sees every device datagram, muted or not
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.front.bind(("127.0.0.1", 0))
        self.port = int(self.front.getsockname()[1])
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.back.bind(("127.0.0.1", 0))
        self.device = ("127.0.0.1", device_port)
        self.host: tuple[str, int] | None = None
        self.mute_device = threading.Event()
        self.mute_host = threading.Event()
        self.last_sample_at = 0.0
        self.last_command_at = 0.0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="relay", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            ready, _, _ = select.select([self.front, self.back], [], [], 0.05)
            for sock in ready:
                data, addr = sock.recvfrom(65536)
                now = time.monotonic()
                if sock is self.front:
                    self.host = addr
                    if not self.mute_host.is_set():
                        self.back.sendto(data, self.device)
                        self.last_command_at = now
                else:
                    if self.on_device is not None:
                        self.on_device(data, now)
                    if self.host is not None and not self.mute_device.is_set():
                        self.front.sendto(data, self.host)
                        self.last_sample_at = now

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)
        self.front.close()
        self.back.close()


@dataclass
class Rig:
    """Device thread, relay and worker; `close()` stops all three."""

    model: RecordingModel | WireRecord
    relay: Relay
    supervisor: WorkerSupervisor
    device_stop: threading.Event
    device_thread: threading.Thread
    stats: list[Any] = field(default_factory=list)
    device_proc: subprocess.Popen[str] | None = None  # the C device

    def locked_since(self, n: int) -> bool:
        """The device applied a lock on each of its last `n` samples."""
        last = self.model.applied[-n:]
        return len(last) == n and all(left or right for _, left, right in last)

    def first_release_after(self, t: float) -> float | None:
        """Monotonic time of the first sample after `t` applied without any lock."""
        for at, left, right in list(self.model.applied):
            if at > t and not (left or right):
                return at
        return None

    def close(self) -> None:
        self.supervisor.stop("rig closed")
        self.device_stop.set()
        if self.device_proc is not None:
            self.device_proc.terminate()  # it prints its statistics and exits
        self.device_thread.join(15.0)
        if self.device_proc is not None and self.device_proc.poll() is None:
            self.device_proc.kill()
            self.device_proc.wait(5)
        self.relay.close()


def _c_device(port: int, key_file: Path, script: str, seed: int
              ) -> tuple[subprocess.Popen[str], Callable[[list[Any]], None]]:
    """The C device on `port`, and a function that waits for it to exit and appends
    its statistics (the JSON line, as attributes) to a list."""
    proc = subprocess.Popen(
        [str(c_device.device_binary()), "--port", str(port), "--seed", str(seed),
         "--script", script, "--key-file", str(key_file), "--python", sys.executable],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def wait(stats: list[Any]) -> None:
        out, _ = proc.communicate()
        lines = [line for line in out.splitlines() if line.startswith("{")]
        if lines:
            stats.append(SimpleNamespace(**json.loads(lines[-1])))

    return proc, wait


def start_rig(folder: Path, script: str = "squat-sequence", seed: int = 1,
              controller: str = "pec", implementation: str = "python") -> Rig:
    """A worker running `controller` on the simulated wearer, through the relay; the
    device is the Python reference device (in a thread) or the C device (a process)."""
    key_file = folder / "device.key"
    key = load_or_create_key(key_file)
    device_port = free_udp_port()
    stop = threading.Event()
    stats: list[Any] = []
    proc: subprocess.Popen[str] | None = None
    model: RecordingModel | WireRecord
    if implementation == "c":
        model = WireRecord()
        proc, wait = _c_device(device_port, key_file, script, seed)
        device = threading.Thread(target=wait, args=(stats,), name="device", daemon=True)
    else:
        python_model = model = RecordingModel(
            SimulatedExoskeleton(seed=seed, script=script, loop=True))

        def run_device() -> None:
            stats.append(serve(device_port, seed, script, "127.0.0.1", stop_event=stop,
                               model=python_model, key=key))

        device = threading.Thread(target=run_device, name="device", daemon=True)
    device.start()
    relay = Relay(device_port, model.datagram if isinstance(model, WireRecord) else None)
    spec = ControllerSpec(controller, ControllerConfig())
    sup = WorkerSupervisor(WorkerConfig(device_kind="udp", device_port=relay.port,
                                        device_key_file=str(key_file), spec=spec),
                           WorkerCallbacks())
    sup.start()
    return Rig(model, relay, sup, stop, device, stats, proc)


def wait_for_lock(rig: Rig, timeout: float = 60.0) -> None:
    """Until the device has held a lock for 5 samples (mid-lift: PEC on a squat)."""
    wait_for(lambda: rig.locked_since(5), timeout,
             f"a lock (worker errors: {rig.supervisor.state.errors})", poll=0.005)


def wait_release(rig: Rig, after: float, timeout: float = 5.0) -> float:
    """The first released sample after `after` (monotonic), waiting for it."""
    return wait_for(lambda: rig.first_release_after(after), timeout,
                    "the device to release", poll=0.005)


# The two watchdog scenarios, shared by the fault test (which asserts what happens) and
# bench/bench_faults.py (which measures how long it takes).

def device_goes_silent(rig: Rig) -> tuple[float, float]:
    """Mid-lift with a lock held, the device's samples stop reaching the worker (left
    muted: the caller clears `rig.relay.mute_device`). Returns (monotonic time of the
    last sample forwarded, time of the first sample the device applied unlocked)."""
    wait_for_lock(rig)
    rig.relay.mute_device.set()
    silent_from = rig.relay.last_sample_at
    return silent_from, wait_release(rig, silent_from)


def worker_freezes(rig: Rig) -> tuple[int, float, float]:
    """With a lock held, the worker gets no CPU (SIGSTOP) until the device has released;
    then it is resumed. Returns (the worker's pid, monotonic time of its last command
    forwarded, time of the first sample the device applied unlocked)."""
    wait_for_lock(rig)
    pid = rig.supervisor.state.pid
    assert pid is not None
    os.kill(pid, signal.SIGSTOP)
    try:
        released = wait_release(rig, time.monotonic())
        return pid, rig.relay.last_command_at, released
    finally:
        os.kill(pid, signal.SIGCONT)
