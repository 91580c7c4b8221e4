"""Kinematics of the activities against the published ranges in docs/simulated-wearer.md."""

from __future__ import annotations

import numpy as np
import pytest

from controller.device.base import SAMPLE_PERIOD_S
from controller.sim.activities import (
    GaitPiece,
    draw_lift,
    gait,
    lift,
    min_jerk,
    stand,
    walk_amplitude,
)
from controller.sim.activity_kinds import ACTIVITY_CODE
from controller.sim.participant import VirtualParticipant

PEOPLE = [VirtualParticipant.from_seed(s) for s in range(12)]


def deg(x: np.ndarray) -> np.ndarray:
    return np.degrees(x)


def test_min_jerk_is_a_smooth_step() -> None:
    u = np.linspace(-0.5, 1.5, 2001)
    s = min_jerk(u)
    assert s[0] == 0.0 and s[-1] == 1.0
    assert np.all(np.diff(s) >= 0)
    assert min_jerk(np.array([0.5]))[0] == pytest.approx(0.5)


@pytest.mark.parametrize("kind", ["squat", "stoop_left", "stoop_right"])
def test_lifts_start_and_end_standing_with_plausible_peaks(kind: str) -> None:
    rng = np.random.default_rng(1)
    peaks, vels = [], []
    for p in PEOPLE:
        shape = draw_lift(p, rng, kind)
        seg = lift(p, shape, 10.0, pick_up=True)
        assert seg.theta[0] == pytest.approx(p.stand_flexion)
        assert seg.theta[-1] == pytest.approx(p.stand_flexion, abs=1e-6)
        assert np.all(seg.activity == ACTIVITY_CODE[kind])
        assert np.all(seg.lift == 0)
        assert seg.progress[0] == 0.0 and seg.progress[-1] == 1.0
        assert np.all(np.diff(seg.progress) > 0)
        peaks.append(deg(seg.theta.max(axis=0)))
        vels.append(np.gradient(seg.theta, SAMPLE_PERIOD_S, axis=0).max())
        # The hip-flexion half is roughly the first half of the lift.
        k_peak = int(seg.theta.sum(axis=1).argmax())
        assert 0.3 < seg.progress[k_peak] < 0.6
    peaks_a = np.array(peaks)
    if kind == "squat":
        assert np.all((peaks_a > 80) & (peaks_a < 120))
        assert 90 <= peaks_a.mean() <= 110
        assert np.abs(peaks_a[:, 0] - peaks_a[:, 1]).max() < 10
    else:
        box, other = (0, 1) if kind == "stoop_left" else (1, 0)
        assert np.all((peaks_a[:, box] > 65) & (peaks_a[:, box] < 105))
        assert 70 <= peaks_a[:, box].mean() <= 100
        assert np.all(peaks_a[:, box] - peaks_a[:, other] > 10)  # off the diagonal
    v = np.array(vels)
    assert np.all((v > 1.4) & (v < 3.9))
    assert 1.9 <= np.median(v) <= 3.0  # spec: peak lifting velocity 2-3 rad/s


def test_repetitions_vary_in_depth_and_speed() -> None:
    p = PEOPLE[0]
    rng = np.random.default_rng(5)
    shapes = [draw_lift(p, rng, "squat") for _ in range(10)]
    depths = np.array([s.peak_deg[0] for s in shapes])
    durations = np.array([s.duration for s in shapes])
    assert depths.std() > 1.0
    assert durations.std() > 0.05
    assert len(set(depths.tolist())) == 10


def test_stand_is_still_and_holding_the_box_costs_a_little() -> None:
    p = PEOPLE[1]
    empty = stand(p, 2.0)
    held = stand(p, 2.0, box_kg=10.0)
    assert empty.n == 201
    assert np.ptp(empty.theta, axis=0) == pytest.approx([0.0, 0.0])
    assert np.all(empty.activity == ACTIVITY_CODE["stand"])
    assert np.all(np.isnan(empty.progress)) and np.all(empty.lift == -1)
    assert np.abs(empty.torque).max() < 1e-9
    assert 5.0 < held.torque.sum(axis=1).mean() < 40.0


def _corr(seg_theta: np.ndarray) -> float:
    return float(np.corrcoef(seg_theta[:, 0], seg_theta[:, 1])[0, 1])


def _steady(p: VirtualParticipant, kind: str, strides: float = 8.0) -> np.ndarray:
    stride = {"walk": p.stride_s, "stairs_up": p.stair_stride_s,
              "stairs_down": 0.9 * p.stair_stride_s}[kind]
    amp = walk_amplitude(p) if kind == "walk" else 1.0
    seg = gait(p, [GaitPiece(kind, strides, stride, (amp, amp))])
    cut = int(1.5 * stride / SAMPLE_PERIOD_S)
    return seg.theta[cut:-cut]


def test_walking_range_antiphase_and_stride() -> None:
    for p in PEOPLE:
        th = _steady(p, "walk")
        rng = deg(np.ptp(th, axis=0))
        assert np.all((rng > 30) & (rng < 52))
        assert 28 <= deg(th.max()) <= 40 and -14 <= deg(th.min()) <= -3
        assert _corr(th) < -0.5
        # Stride from the left hip's autocorrelation.
        x = th[:, 0] - th[:, 0].mean()
        ac = np.correlate(x, x, "full")[x.size - 1 :]
        lag = int(np.argmax(ac[50:200])) + 50
        # The autocorrelation's peak resolves the stride to a sample or two.
        assert 1.0 - 0.02 <= lag * SAMPLE_PERIOD_S <= 1.2 + 0.02
        assert lag * SAMPLE_PERIOD_S == pytest.approx(p.stride_s, abs=0.02)


def test_stairs_ranges_and_antiphase() -> None:
    for p in PEOPLE:
        up = _steady(p, "stairs_up")
        down = _steady(p, "stairs_down")
        assert np.all(np.abs(deg(np.ptp(up, axis=0)) - 60) < 8)
        assert 58 <= deg(up.max()) <= 70
        assert np.all(np.abs(deg(np.ptp(down, axis=0)) - 30) < 6)
        assert _corr(up) < -0.5 and _corr(down) < -0.5


def test_stair_ascent_looks_like_an_asymmetric_stoop() -> None:
    """The paper's hard case: one hip flexed 60-65 deg while the other is much less."""
    p = PEOPLE[2]
    up = deg(_steady(p, "stairs_up"))
    high = up.max(axis=1) > 55
    assert high.any()
    low = up.min(axis=1)[high]
    assert np.all(low < 35)


def test_gait_bout_is_smooth_and_labelled_by_piece() -> None:
    p = PEOPLE[3]
    pieces = [
        GaitPiece("walk", 3.0, p.stride_s),
        GaitPiece("turn", 2.0, 1.15 * p.stride_s, (0.6, 0.5)),
        GaitPiece("stairs_up", 5.5, p.stair_stride_s),
    ]
    seg = gait(p, pieces)
    assert seg.theta[0] == pytest.approx(p.stand_flexion)
    assert seg.theta[-1] == pytest.approx(p.stand_flexion, abs=1e-4)
    codes = [ACTIVITY_CODE[k] for k in ("walk", "turn", "stairs_up")]
    changes = seg.activity[np.flatnonzero(np.diff(seg.activity)) + 1]
    assert [int(seg.activity[0]), *changes.tolist()] == codes
    acc = np.gradient(np.gradient(seg.theta, SAMPLE_PERIOD_S, axis=0), SAMPLE_PERIOD_S, axis=0)
    assert np.abs(acc).max() < 80.0  # rad/s^2, no jumps a Kalman filter would see
    with pytest.raises(ValueError):
        gait(p, [])
    with pytest.raises(ValueError):
        GaitPiece("run", 1.0, 1.0)


def test_either_leg_can_lead_a_gait_bout() -> None:
    p = PEOPLE[4]
    piece = [GaitPiece("walk", 4.0, p.stride_s)]
    k = int(0.4 * p.stride_s / SAMPLE_PERIOD_S)  # the first swing
    left_first = gait(p, piece, lead="left").theta[k]
    right_first = gait(p, piece, lead="right").theta[k]
    assert left_first[0] > left_first[1]
    assert right_first[1] > right_first[0]
    with pytest.raises(ValueError):
        gait(p, piece, lead="both")

