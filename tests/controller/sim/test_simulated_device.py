"""SimulatedDevice: the simulated exoskeleton behind the Device interface."""

from __future__ import annotations

import time

from controller.device.base import LockCommand, Status
from controller.sim.simulated_device import SimulatedDevice


def test_free_running_reads_and_commands() -> None:
    dev = SimulatedDevice(seed=1, script="walking", realtime=False, loop=False)
    assert dev.kind == "simulated"
    with dev:
        # Free running: no pacing (its speed is bench/bench_device_calls.py's).
        first = [dev.read(1.0) for _ in range(200)]
        assert [s.seq for s in first if s is not None] == list(range(200))
        dev.send(LockCommand(5, True, True))
        s = dev.read(1.0)
        assert s is not None and s.status & Status.SOLENOID_LEFT
        s = dev.read(1.0)  # the command is held
        assert s is not None and s.status & Status.SOLENOID_RIGHT
        dev.release()
        s = dev.read(1.0)
        assert s is not None and not s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT)
        n = 203
        while dev.read(0.0) is not None:
            n += 1
        assert n == round(dev.exo.duration / dev.exo.dt)
        assert dev.exo.finished


def test_realtime_paces_at_100_hz_without_drift() -> None:
    """Samples are never early, and a late reader gets the waiting ones at once.

    Only the lower bound is a property of the device; how late a loaded machine reads
    is not, so no upper bound on wall-clock time is asserted (bench/ measures it).
    """
    dev = SimulatedDevice(seed=2, script="stairs", realtime=True)
    dev.open()
    start = time.monotonic()
    for _ in range(30):
        assert dev.read(1.0) is not None
    assert time.monotonic() - start >= 0.28  # sample 29 is due at 0.29 s
    time.sleep(0.05)  # a late reader gets the waiting samples without waiting
    for _ in range(4):
        assert dev.read(0.0) is not None
    dev.close()
