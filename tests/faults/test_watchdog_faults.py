"""A device that goes silent mid-lift while locked, and a worker starved of the CPU:
the device's watchdog lets go of the solenoids in both cases.

The figures (release time after silence) go to the README from bench/bench_faults.py;
here the release itself is asserted, with a loose bound that only catches a watchdog
that does not work at all.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from tests.faults.rig import start_rig, wait_for_lock, wait_release
from tests.faults.served import wait_for

pytestmark = pytest.mark.slow


def test_device_silent_mid_lift_then_worker_frozen_both_release(tmp_path: Path) -> None:
    rig = start_rig(tmp_path)
    try:
        # 1. The device stops sending mid-lift: the worker hears nothing, so it commands
        # nothing, and the device's watchdog releases.
        wait_for_lock(rig)
        rig.relay.mute_device.set()
        silent_from = rig.relay.last_sample_at
        released = wait_release(rig, silent_from)
        assert released - silent_from < 1.0
        # No lock is applied after the release while the device stays silent.
        time.sleep(0.3)
        assert not any(left or right for at, left, right in rig.model.applied
                       if at > released)
        rig.relay.mute_device.clear()

        # 2. The worker gets no CPU at all (SIGSTOP) while a lock is held.
        wait_for_lock(rig)
        pid = rig.supervisor.state.pid
        assert pid is not None
        os.kill(pid, signal.SIGSTOP)
        try:
            stopped_at = time.monotonic()
            released = wait_release(rig, stopped_at)
            assert released - rig.relay.last_command_at < 1.0
        finally:
            os.kill(pid, signal.SIGCONT)
        # The worker resumes and controls again (still the same process).
        n = len(rig.model.applied)
        wait_for(lambda: rig.relay.last_command_at > time.monotonic() - 0.1
                 and len(rig.model.applied) > n + 50, 30, "the worker to resume")
        assert rig.supervisor.state.alive and rig.supervisor.state.pid == pid
    finally:
        rig.close()
    assert rig.stats and rig.stats[0].watchdog_releases >= 2
