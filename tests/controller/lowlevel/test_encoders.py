"""Encoder counts to angles: offsets, direction, wrap-around."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.lowlevel.encoders import RAD_PER_COUNT, EncoderLayout

angles = st.floats(min_value=-math.pi + 1e-3, max_value=math.pi - 1e-3)


def test_resolution_is_the_as5048a_one() -> None:
    assert math.degrees(RAD_PER_COUNT) == pytest.approx(0.0219727, abs=1e-6)


@given(st.integers(0, 3), angles, st.integers(0, 16383))
def test_count_then_angle_round_trips_within_half_a_count(i: int, angle: float, off: int) -> None:
    layout = EncoderLayout(offsets=(off, off, off, off), directions=(1, -1, 1, -1))
    back = layout.angle(i, layout.count(i, angle))
    assert abs(back - angle) <= RAD_PER_COUNT / 2 + 1e-12


def test_wrap_around_near_the_offset() -> None:
    layout = EncoderLayout(offsets=(5, 5, 5, 5))
    # Three counts below an offset of 5 wraps to 16382: still a small negative angle.
    assert layout.angle(0, 2) == pytest.approx(-3 * RAD_PER_COUNT)
    assert layout.angle(0, 16383) == pytest.approx(-6 * RAD_PER_COUNT)


def test_mirrored_right_side_reads_flexion_positive() -> None:
    layout = EncoderLayout()
    counts = layout.encode(0.5, 0.5, 0.7, 0.6)
    ql, al, qr, ar = layout.joint_angles(counts)
    assert ql == pytest.approx(0.5, abs=RAD_PER_COUNT)
    assert qr == pytest.approx(0.7, abs=RAD_PER_COUNT)
    assert al == pytest.approx(0.0, abs=2 * RAD_PER_COUNT)
    assert ar == pytest.approx(0.1, abs=2 * RAD_PER_COUNT)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"offsets": (0, 0, 0, 16384)}, "encoder 3: offset 16384"),
        ({"directions": (1, 1, 0, 1)}, "encoder 2: direction"),
    ],
)
def test_bad_layouts_are_refused_with_the_encoder_named(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        EncoderLayout(**kwargs)


def test_out_of_range_count_is_refused() -> None:
    with pytest.raises(ValueError, match="encoder 1: count 20000"):
        EncoderLayout().angle(1, 20000)
