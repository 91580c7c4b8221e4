"""Scripts: the paper's protocol, ground truth, determinism and variation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device.base import SAMPLE_PERIOD_S
from controller.sim.activity_kinds import ACTIVITIES
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import SCRIPT_NAMES, Trajectory, get_script, realise

P = VirtualParticipant.from_seed(4)


def run(name: str, seed: int = 4, rep: int = 0) -> Trajectory:
    return realise(get_script(name), P, seed, rep)


def lift_kinds(tr: Trajectory) -> list[str]:
    names = tr.activity_names()
    return [str(names[tr.lift == i][0]) for i in range(tr.n_lifts)]


def test_builtin_names_and_unknown_name() -> None:
    assert set(SCRIPT_NAMES) == {
        "squat-sequence", "stoop-sequence", "walking", "stairs", "paper-evaluation",
        "lift-evaluation", "standing", "hip-flex-left", "hip-flex-right",
    }
    with pytest.raises(ValueError, match="squat-sequence"):
        get_script("jumping")


def test_squat_sequence_has_ten_squat_lifts_with_one_second_holds() -> None:
    tr = run("squat-sequence")
    assert tr.n_lifts == 10
    assert lift_kinds(tr) == ["squat"] * 10
    assert get_script("squat-sequence").box_kg == 10.0
    # Between pick-up (even) and put-down (odd) the wearer stands about one second.
    for i in range(0, 10, 2):
        end = np.flatnonzero(tr.lift == i)[-1]
        start = np.flatnonzero(tr.lift == i + 1)[0]
        assert 0.7 <= (start - end) * SAMPLE_PERIOD_S <= 1.4


def test_stoop_sequence_alternates_sides() -> None:
    tr = run("stoop-sequence")
    kinds = lift_kinds(tr)
    assert kinds.count("stoop_left") == 5 and kinds.count("stoop_right") == 5
    assert all(a != b for a, b in zip(kinds[::2], kinds[1::2], strict=True))


def test_walking_and_stairs_have_the_paper_structure() -> None:
    walk = run("walking")
    names = walk.activity_names()
    assert set(names) == {"stand", "walk", "turn"}
    assert 18.0 < walk.duration < 35.0
    assert walk.n_lifts == 0 and np.all(walk.lift == -1)
    stairs = run("stairs")
    names = stairs.activity_names()
    up = (names == "stairs_up").sum() * SAMPLE_PERIOD_S
    down = (names == "stairs_down").sum() * SAMPLE_PERIOD_S
    assert up == pytest.approx(5.5 * P.stair_stride_s, rel=0.1)  # 11 steps
    assert down == pytest.approx(5.5 * 0.9 * P.stair_stride_s, rel=0.1)
    first_up = np.flatnonzero(names == "stairs_up")[0]
    first_down = np.flatnonzero(names == "stairs_down")[0]
    assert "turn" in set(names[first_up:first_down])


def test_paper_evaluation_covers_everything_with_truth() -> None:
    tr = run("paper-evaluation")
    assert get_script("paper-evaluation").box_kg == 5.0
    assert set(tr.activity_names()) == set(ACTIVITIES)
    assert tr.n_lifts == 20
    assert sorted(set(tr.lift.tolist())) == list(range(-1, 20))
    inside = tr.lift >= 0
    assert np.all(np.isnan(tr.progress[~inside]))
    assert np.all((tr.progress[inside] >= 0) & (tr.progress[inside] <= 1))
    for i in range(20):
        pr = tr.progress[tr.lift == i]
        assert pr[0] == 0.0 and pr[-1] == 1.0 and np.all(np.diff(pr) > 0)
    assert np.allclose(np.diff(tr.t), SAMPLE_PERIOD_S)
    assert 150.0 < tr.duration < 260.0
    # Smooth everywhere: no sample-to-sample jump beyond what 4 rad/s allows.
    assert np.abs(np.diff(tr.theta, axis=0)).max() < 0.045
    assert np.all(np.isfinite(tr.theta)) and np.all(np.isfinite(tr.torque))


def test_same_seed_same_run_other_seed_or_repetition_differs() -> None:
    a, b = run("squat-sequence"), run("squat-sequence")
    assert np.array_equal(a.theta, b.theta) and np.array_equal(a.activity, b.activity)
    c = run("squat-sequence", seed=5)
    d = run("squat-sequence", rep=1)
    for other in (c, d):
        assert other.n != a.n or not np.allclose(other.theta, a.theta)


def test_lifts_within_a_run_differ() -> None:
    tr = run("squat-sequence")
    peaks = [np.degrees(tr.theta[tr.lift == i, 0].max()) for i in range(tr.n_lifts)]
    lengths = [(tr.lift == i).sum() for i in range(tr.n_lifts)]
    assert np.std(peaks) > 1.0
    assert len(set(lengths)) > 5


def test_time_offset_and_lift_numbering() -> None:
    tr = realise(get_script("squat-sequence"), P, 4, 1, t0=100.0, lift_offset=10)
    assert tr.t[0] == 100.0
    assert sorted(set(tr.lift.tolist())) == [-1, *range(10, 20)]


def test_hip_flex_moves_one_hip_40_degrees_and_back() -> None:
    for name, side in (("hip-flex-left", 0), ("hip-flex-right", 1)):
        tr = run(name)
        moved = np.degrees(tr.theta[:, side] - tr.theta[0, side])
        still = np.degrees(tr.theta[:, 1 - side] - tr.theta[0, 1 - side])
        assert moved.max() == pytest.approx(40.0, abs=1.5)  # plus the participant's sway
        assert abs(moved[-1]) < 1.5
        assert np.abs(still).max() < 1.5
        assert tr.n_lifts == 0
        assert set(tr.activity_names().tolist()) == {"stand"}


@settings(max_examples=6, deadline=None)
@given(name=st.sampled_from(SCRIPT_NAMES), seed=st.integers(0, 10_000),
       rep=st.integers(0, 3))
def test_angles_without_moments_are_the_same_draws_and_angles(name: str, seed: int,
                                                               rep: int) -> None:
    p = VirtualParticipant.from_seed(seed)
    full = realise(get_script(name), p, seed, rep)
    bare = realise(get_script(name), p, seed, rep, moments=False)
    # Bit for bit: the cohort's replay reads only these, and its numbers must not move.
    assert np.array_equal(bare.t, full.t) and np.array_equal(bare.theta, full.theta)
    assert np.array_equal(bare.activity, full.activity)
    assert np.array_equal(bare.lift, full.lift) and bare.n_lifts == full.n_lifts
    assert np.array_equal(bare.progress, full.progress, equal_nan=True)
    # Moments not computed are NaN, never a plausible 0 Nm; computed ones are finite.
    assert np.isnan(bare.torque).all() and np.isfinite(full.torque).all()
