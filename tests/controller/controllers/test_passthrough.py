"""Recording mode: angles from counts, never a lock, bad samples flagged."""

from __future__ import annotations

import math

import pytest

from controller.controllers.passthrough import PassThroughController
from controller.device.base import GroundTruth, Sample, Status
from controller.lowlevel.encoders import DEFAULT_LAYOUT
from controller.tick_record import Action, Plausibility, TickFlag


def test_angles_and_deflection_from_counts() -> None:
    counts = DEFAULT_LAYOUT.encode(0.8, 0.6, 0.3, 0.3)
    rec = PassThroughController().step(
        Sample(seq=3, t=0.03, counts=counts, status=Status.LOCKED_LEFT,
               truth=GroundTruth("squat", 2, 0.25))
    )
    assert rec.q_left == pytest.approx(0.8, abs=1e-3)
    assert rec.q_right == pytest.approx(0.3, abs=1e-3)
    assert rec.alpha_left == pytest.approx(0.2, abs=1e-3)
    assert rec.alpha_right == pytest.approx(0.0, abs=1e-3)
    assert rec.locked_left and not rec.locked_right
    assert (rec.lock_left, rec.lock_right, rec.action) == (False, False, Action.NO_LOCK)
    assert (rec.truth_activity, rec.truth_lift, rec.truth_progress) == ("squat", 2, 0.25)
    assert rec.flags == 0


def test_out_of_range_count_is_a_flagged_tick_not_an_exception() -> None:
    rec = PassThroughController().step(Sample(seq=1, t=0.0, counts=(0, 0, 70000, 0)))
    assert rec.flags & TickFlag.BAD_SAMPLE
    assert math.isnan(rec.q_left)
    assert not rec.lock_left and not rec.lock_right


def test_device_fault_is_flagged() -> None:
    rec = PassThroughController().step(
        Sample(seq=1, t=0.0, counts=(3100, 3100, 12900, 12900), status=Status.ENCODER_FAULT)
    )
    assert rec.flags & TickFlag.DEVICE_FAULT


def test_recording_mode_flags_implausible_samples_too() -> None:
    ctl = PassThroughController()
    still = DEFAULT_LAYOUT.encode(0.1, 0.1, 0.1, 0.1)
    jump = DEFAULT_LAYOUT.encode(1.0, 1.0, 0.1, 0.1)  # 90 rad/s for 10 ms
    out = [ctl.step(Sample(seq=k, t=0.01 * k, counts=still)) for k in range(5)]
    out.append(ctl.step(Sample(seq=5, t=0.05, counts=jump)))
    out.append(ctl.step(Sample(seq=6, t=0.06, counts=still)))
    out.append(ctl.step(Sample(seq=6, t=0.06, counts=still)))  # the same sample again
    assert [r.plausibility for r in out] == [0] * 5 + [int(Plausibility.JUMP), 0,
                                                       int(Plausibility.REPEATED)]
    assert out[5].flags == TickFlag.IMPLAUSIBLE
    assert out[5].q_raw_left == pytest.approx(1.0, abs=1e-3)  # kept: nothing decides on it
    assert not any(r.lock_left or r.lock_right for r in out)
