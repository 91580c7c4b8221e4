"""SimulatedExoskeleton: interface, determinism, sensing and the mechanism in a session."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.device.base import LockCommand, Status
from controller.lowlevel.actuator import maccepa_torque
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.activity_kinds import ACTIVITIES
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.participant import VirtualParticipant


def test_interface_and_unknown_script() -> None:
    exo = SimulatedExoskeleton(seed=1, script="walking")
    assert exo.dt == 0.01
    assert 15.0 < exo.duration < 40.0
    assert exo.finished is False
    assert exo.participant == VirtualParticipant.from_seed(1)
    with pytest.raises(ValueError, match="paper-evaluation"):
        SimulatedExoskeleton(script="yoga")


def test_runs_to_the_end_with_consecutive_samples_and_truth() -> None:
    exo = SimulatedExoskeleton(seed=2, script="walking")
    samples = []
    while not exo.finished:
        samples.append(exo.tick(None))
    assert len(samples) == round(exo.duration / exo.dt)
    assert [s.seq for s in samples] == list(range(len(samples)))
    assert samples[10].t == pytest.approx(0.10)
    assert all(s.truth is not None and s.truth.activity in ACTIVITIES for s in samples)
    assert all(s.status == Status.NONE for s in samples)
    after = exo.tick(None)  # holds the final standing posture
    assert after.seq == len(samples) and after.truth is not None
    assert after.truth.activity == "stand"


def test_same_seed_identical_other_seed_different() -> None:
    def counts(seed: int) -> list[tuple[int, int, int, int]]:
        exo = SimulatedExoskeleton(seed=seed, script="stairs")
        return [exo.tick(None).counts for _ in range(800)]

    assert counts(3) == counts(3)
    assert counts(3) != counts(4)


def test_encoders_read_the_true_angle_plus_the_donning_offset() -> None:
    layout = EncoderLayout(offsets=(100, 200, 16000, 8000))
    exo = SimulatedExoskeleton(seed=5, script="squat-sequence", layout=layout)
    errs = []
    for _ in range(1500):
        s = exo.tick(None)
        th_l, al_l, th_r, al_r = layout.joint_angles(s.counts)
        true_l, true_r = exo.true_angles()
        off = exo.participant.encoder_offset(np.array([s.t]))[0]
        errs.append((th_l - true_l - off[0], th_r - true_r - off[1]))
        assert abs(al_l) < math.radians(1.7) and abs(al_r) < math.radians(1.7)
    err = np.degrees(np.array(errs))
    assert np.abs(err).max() < 1.0  # non-linearity (<= 0.75 deg) plus noise
    assert np.abs(exo.participant.offset_deg).max() > 0.5  # the offset is really there


def test_locking_in_a_squat_gives_torque_and_no_command_gives_none() -> None:
    exo = SimulatedExoskeleton(seed=6, script="squat-sequence", precompression_pct=25.0)
    peak = [0.0, 0.0]
    locked_seen = False
    s = exo.tick(None)
    while True:
        truth = s.truth
        assert truth is not None
        if truth.lift_index == 1 and truth.progress > 0.99:
            break
        # Lock both sides from the very start of every lift's flexion.
        cmd = truth.lift_index >= 0 and truth.progress < 0.3
        s = exo.tick(LockCommand(s.seq, cmd, cmd))
        tl, tr = exo.true_torques()
        peak = [max(peak[0], tl), max(peak[1], tr)]
        if s.status & Status.LOCKED_LEFT:
            locked_seen = True
            al, _ar = exo.alphas()
            assert tl == pytest.approx(maccepa_torque(al, 25.0))
    assert locked_seen
    assert peak[0] > 15.0 and peak[1] > 15.0

    free = SimulatedExoskeleton(seed=6, script="squat-sequence")
    for _ in range(1500):
        s = free.tick(None)
        assert not s.status & (Status.LOCKED_LEFT | Status.LOCKED_RIGHT)
        assert free.true_torques() == (0.0, 0.0)


def test_none_keeps_the_previous_command() -> None:
    exo = SimulatedExoskeleton(seed=0, script="walking")
    s = exo.tick(LockCommand(0, True, False))
    assert s.status & Status.SOLENOID_LEFT and not s.status & Status.SOLENOID_RIGHT
    s = exo.tick(None)
    assert s.status & Status.SOLENOID_LEFT
    s = exo.tick(LockCommand(1, False, False))
    assert not s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT)


def test_loop_keeps_going_with_new_repetitions() -> None:
    exo = SimulatedExoskeleton(seed=7, script="squat-sequence", loop=True)
    n = round(exo.duration / exo.dt)
    first = [exo.tick(None) for _ in range(n)]
    second = [exo.tick(None) for _ in range(n)]
    assert not exo.finished
    assert second[0].seq == n and second[0].t == pytest.approx(n * 0.01)
    lifts = {s.truth.lift_index for s in first + second if s.truth is not None}
    assert {0, 9, 10, 15} <= lifts
    assert [s.counts for s in first[300:600]] != [s.counts for s in second[300:600]]
    # Continuous at the seam: no jump in the measured hip angle.
    a = DEFAULT_LAYOUT.joint_angles(first[-1].counts)[0]
    b = DEFAULT_LAYOUT.joint_angles(second[0].counts)[0]
    assert abs(a - b) < math.radians(0.5)
