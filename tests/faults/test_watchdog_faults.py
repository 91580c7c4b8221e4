"""A device that goes silent mid-lift while locked, and a worker starved of the CPU:
the device's watchdog lets go of the solenoids in both cases.

The figures (release time after silence) go to the README from bench/bench_faults.py,
which runs the same two scenarios (`tests/faults/rig.py`); here the release itself is
asserted: a watchdog that does not work fails the bounded wait for the release.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.faults.rig import device_goes_silent, start_rig, worker_freezes
from tests.polling import wait_for

pytestmark = pytest.mark.slow


def test_device_silent_mid_lift_then_worker_frozen_both_release(
        tmp_path: Path, device_implementation: str) -> None:
    rig = start_rig(tmp_path, implementation=device_implementation)
    try:
        # 1. The device stops sending mid-lift: the worker hears nothing, so it commands
        # nothing, and the device's watchdog releases.
        silent_from, released = device_goes_silent(rig)
        assert released > silent_from
        # No lock is applied after the release while the device stays silent: watch the
        # device's next 30 samples (0.3 s of its own clock).
        seen = len(rig.model.applied)
        wait_for(lambda: len(rig.model.applied) >= seen + 30, 10, "30 more device samples")
        assert not any(left or right for at, left, right in rig.model.applied
                       if at > released)
        rig.relay.mute_device.clear()

        # 2. The worker gets no CPU at all (SIGSTOP) while a lock is held.
        pid, last_command, released = worker_freezes(rig)
        assert released > last_command
        # The worker resumes and controls again (still the same process).
        n = len(rig.model.applied)
        wait_for(lambda: rig.relay.last_command_at > time.monotonic() - 0.1
                 and len(rig.model.applied) > n + 50, 30, "the worker to resume")
        assert rig.supervisor.state.alive and rig.supervisor.state.pid == pid
    finally:
        rig.close()
    assert rig.stats and rig.stats[0].watchdog_releases >= 2
