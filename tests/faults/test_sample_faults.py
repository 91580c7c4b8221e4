"""Implausible samples on the real processes (a device process over UDP, the worker):
encoder glitches, 228 rad/s hip velocities, and a device sending ten times too fast.
Before the plausibility checks, 5 % glitches in a squat stream nearly doubled the PEC's
locks, and a one-sample spike on both hips read as a 228 rad/s hip and locked."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from controller.device.auth import create_key
from controller.lowlevel.plausibility import HIP_VELOCITY_MAX
from controller.tick_record import Plausibility, TickFlag, TickRecord
from tests.faults.device_rig import Worker, device_process, lock_onsets, model_device_process
from tests.faults.glitchy_device import SPIKE_EVERY, serve_glitchy
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow


@pytest.fixture
def key_file(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "device.key"
    create_key(path)
    yield path


def _locks_per_lift(records: list[TickRecord]) -> tuple[Counter[int], int]:
    """Lock onsets per lift of the wearer (ground truth), and onsets outside lifts."""
    per_lift: Counter[int] = Counter()
    outside = 0
    for i in lock_onsets(records):
        if records[i].truth_lift >= 0:
            per_lift[records[i].truth_lift] += 1
        else:
            outside += 1
    return per_lift, outside


def test_glitches_and_228_rad_per_s_spikes_add_no_lock(key_file: Path) -> None:
    port = free_udp_port()
    with model_device_process(serve_glitchy, port, str(key_file), 1, "squat-sequence"), \
            Worker(port, key_file, "pec") as worker:
        wait_for(lambda: len({r.truth_lift for r in worker.ticks() if r.truth_lift >= 0}) >= 3,
                 120, "three squats")
        records = worker.ticks()
        status = worker.sup.state.status

    assert len(records) > 800
    flagged = [r for r in records if r.flags & (TickFlag.IMPLAUSIBLE | TickFlag.BAD_SAMPLE)]
    # About 5 % glitches plus one spike in 97, each flagged (a glitch small enough to
    # look like motion is not; one landing on a sample already off course counts once).
    share = len(flagged) / len(records)
    assert 0.03 < share < 0.09, share
    spikes = [r for r in records if r.plausibility & (Plausibility.JUMP | Plausibility.RANGE)]
    assert len(spikes) >= len(records) // SPIKE_EVERY - 1
    # No hip velocity the filter reports is beyond a hip's: the spikes never reached it.
    assert max(max(abs(r.omega_left), abs(r.omega_right)) for r in records
               if r.omega_left == r.omega_left) < HIP_VELOCITY_MAX
    # One lock per squat, as without glitches, and none while standing.
    per_lift, outside = _locks_per_lift(records)
    assert outside == 0
    assert len(per_lift) >= 2 and set(per_lift.values()) == {1}, per_lift
    assert status is not None and status.device.implausible_samples > 0
    print(f"glitches + spikes: {len(records)} ticks, {len(flagged)} flagged "
          f"({100 * share:.1f} %), {len(spikes)} of them angle jumps or out of range, "
          f"lock onsets per squat "
          f"{dict(per_lift)}, {outside} while standing")


def test_a_device_sending_ten_times_too_fast_gets_no_extra_lock(
        key_file: Path, device_implementation: str) -> None:
    port = free_udp_port()
    with device_process(port, key_file, "squat-sequence", extra=("--rate-factor", "10"),
                        implementation=device_implementation), \
            Worker(port, key_file, "pec") as worker:
        wait_for(lambda: len({r.truth_lift for r in worker.ticks() if r.truth_lift >= 0}) >= 2,
                 120, "two squats at ten times the sample rate")
        records = worker.ticks()

    assert len(records) > 3000  # the worker kept up with 1 kHz
    early = sum(bool(r.plausibility & Plausibility.TOO_EARLY) for r in records)
    # Samples 1 ms apart: four of five come less than 5 ms after the last one used.
    assert 0.75 < early / len(records) < 0.85
    per_lift, outside = _locks_per_lift(records)
    assert outside == 0
    assert set(per_lift.values()) <= {1}
    # Velocities stay those of a squat, whatever the rate.
    top = max(max(abs(r.omega_left), abs(r.omega_right)) for r in records
              if r.omega_left == r.omega_left)
    assert top < 5.0
    print(f"10x rate: {len(records)} ticks, {100 * early / len(records):.1f} % too early, "
          f"lock onsets per squat {dict(per_lift)}, {outside} while standing, "
          f"top velocity {top:.2f} rad/s")
