"""Bring-up arithmetic (controller/lowlevel/bringup.py): counts generated through an
`EncoderLayout` with known zeros and signs must give those zeros and signs back."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device.base import ENCODER_COUNTS, Status
from controller.lowlevel import bringup as calc
from controller.lowlevel.encoders import EncoderLayout

counts_st = st.integers(0, ENCODER_COUNTS - 1)
sign_st = st.sampled_from((1, -1))


def rows(layout: EncoderLayout, out_l: np.ndarray, cam_l: np.ndarray, out_r: np.ndarray,
         cam_r: np.ndarray, status: int = 0) -> np.ndarray:
    """Raw samples (arrival, seq, t, 4 counts, status) of these link angles (rad)."""
    return np.array([(0.01 * k, k, 0.01 * k, *layout.encode(a, b, c, d), status)
                     for k, (a, b, c, d) in enumerate(zip(out_l, cam_l, out_r, cam_r,
                                                           strict=True))], dtype=np.float64)


@settings(max_examples=40, deadline=None)
@given(st.tuples(counts_st, counts_st, counts_st, counts_st),
       st.tuples(sign_st, sign_st, sign_st, sign_st), st.integers(0, 2**31))
def test_zero_finds_each_encoders_count_at_standing(offsets: tuple[int, int, int, int],
                                                    signs: tuple[int, int, int, int],
                                                    seed: int) -> None:
    layout = EncoderLayout(offsets, signs)
    rng = np.random.default_rng(seed)
    still = [rng.normal(0.0, math.radians(0.06), 200) for _ in range(4)]
    z = calc.zero(rows(layout, still[0], still[1], still[2], still[3]))
    for got, want in zip(z.offsets, offsets, strict=True):
        # Within a count of the true zero, also across the wrap at 16383 -> 0.
        assert abs(int(calc.wrap(got - want))) <= 1
    assert all(s < 0.1 for s in z.std_deg)


def test_zero_refuses_a_moving_or_locked_capture() -> None:
    layout = EncoderLayout()
    t = np.linspace(0.0, 2.0, 200)
    zeros = np.zeros(200)
    swaying = np.radians(5.0) * np.sin(2 * np.pi * t)
    with pytest.raises(calc.BringupError, match="not still: right output, right cam moved"):
        calc.zero(rows(layout, zeros, zeros, swaying, swaying))
    with pytest.raises(calc.BringupError, match="a pawl engaged"):
        calc.zero(rows(layout, zeros, zeros, zeros, zeros, int(Status.LOCKED_LEFT)))
    with pytest.raises(calc.BringupError, match="no samples"):
        calc.zero(np.zeros((0, 8)))


def flex(deg: float, n: int = 300, start: float = 0.0) -> np.ndarray:
    """A hip from standing up by `deg` and back, starting `start` of the way through."""
    phase = (np.linspace(0.0, 1.0, n) + start) % 1.0
    return np.radians(deg) * np.sin(np.pi * phase) ** 2


@settings(max_examples=40, deadline=None)
@given(st.tuples(counts_st, counts_st, counts_st, counts_st),
       st.tuples(sign_st, sign_st, sign_st, sign_st), st.sampled_from(("left", "right")),
       st.floats(0.0, 0.99))
def test_direction_recovers_the_mounting_signs(offsets: tuple[int, int, int, int],
                                               signs: tuple[int, int, int, int], side: str,
                                               start: float) -> None:
    layout = EncoderLayout(offsets, signs)
    moving, still = flex(40.0, start=start), np.zeros(300)
    links = (moving, moving, still, still) if side == "left" else (still, still, moving, moving)
    # With the standing counts as reference the capture may start anywhere in the flexion.
    d = calc.direction(rows(layout, *links), side, reference=offsets)
    out, cam = calc.INDEX[side]
    assert (d.output_direction, d.cam_direction) == (signs[out], signs[cam])
    assert d.moved_deg == pytest.approx(40.0, abs=0.1)
    assert d.other_moved_deg < 0.1


def test_direction_fails_clearly_when_the_wrong_side_moved() -> None:
    layout, moving, still = EncoderLayout(), flex(30.0), np.zeros(300)
    right_moved = rows(layout, still, still, moving, moving)
    with pytest.raises(calc.BringupError, match=r"the right hip moved .*not the left"):
        calc.direction(right_moved, "left")
    both = rows(layout, moving, moving, moving, moving)
    with pytest.raises(calc.BringupError, match="both hips moved"):
        calc.direction(both, "left")
    small = rows(layout, flex(4.0), flex(4.0), still, still)
    with pytest.raises(calc.BringupError, match=r"moved only 4\.0 deg"):
        calc.direction(small, "left")
    locked = rows(layout, moving, still, still, still)
    with pytest.raises(calc.BringupError, match="cam link did not follow"):
        calc.direction(locked, "left")


@settings(max_examples=40, deadline=None)
@given(st.tuples(counts_st, counts_st, counts_st, counts_st),
       st.tuples(sign_st, sign_st, sign_st, sign_st))
def test_cam_offset_makes_alpha_zero_while_unlocked(offsets: tuple[int, int, int, int],
                                                    signs: tuple[int, int, int, int]) -> None:
    truth = EncoderLayout(offsets, signs)
    links = flex(30.0)
    samples = rows(truth, links, links, links, links)
    # Start from wrong cam zeros: the step must find the true ones.
    guess = EncoderLayout((offsets[0], (offsets[1] + 500) % ENCODER_COUNTS, offsets[2],
                           (offsets[3] + 9000) % ENCODER_COUNTS), signs)
    c = calc.cam_offset(samples, guess)
    assert c.cam_offsets == (offsets[1], offsets[3])
    assert c.cam_output_offsets == (int(calc.wrap(offsets[1] - offsets[0])),
                                    int(calc.wrap(offsets[3] - offsets[2])))
    assert max(c.alpha_max_deg) < 0.05  # quantisation only
    fixed = EncoderLayout((offsets[0], c.cam_offsets[0], offsets[2], c.cam_offsets[1]), signs)
    for row in samples[::37]:
        c0, c1, c2, c3 = (int(v) for v in row[3:7])
        _, alpha_l, _, alpha_r = fixed.joint_angles((c0, c1, c2, c3))
        assert abs(alpha_l) < 1e-3 and abs(alpha_r) < 1e-3


def test_cam_offset_refuses_a_side_whose_cam_does_not_follow() -> None:
    layout, still = EncoderLayout(), np.zeros(300)
    with pytest.raises(calc.BringupError, match="left: alpha reaches"):
        calc.cam_offset(rows(layout, flex(20.0), still, still, still), layout)
