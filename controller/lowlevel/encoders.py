"""Encoder counts to joint angles: offsets, mounting direction and wrap-around.

The AS5048A is absolute over one turn, so an angle is the count difference from a
mounting offset, wrapped into half a turn either side. The right side is mounted
mirrored, hence a direction of -1 there by default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from controller.device.base import ENCODER_COUNTS

RAD_PER_COUNT = 2.0 * math.pi / ENCODER_COUNTS
_HALF_TURN = ENCODER_COUNTS // 2


@njit("float64(int64, int64, int64)", cache=True, nogil=True)
def count_to_angle(count: int, offset: int, direction: int) -> float:
    """Angle (rad, in [-pi, pi)) of a count; the arithmetic of `EncoderLayout.angle`.

    Compiled so the control tick (`controller.kernel.tick`) decodes counts with the very
    code the layout uses; the count must already be known to lie in range.
    """
    diff = (count - offset) % ENCODER_COUNTS
    if diff >= _HALF_TURN:
        diff -= ENCODER_COUNTS
    return direction * diff * RAD_PER_COUNT


@njit("int64(float64, int64, int64)", cache=True, nogil=True)
def angle_to_count(angle: float, offset: int, direction: int) -> int:
    """The count an ideal encoder reads at `angle` (rad); rounds halves to even, like
    Python's `round`, so the layout and the batch replay quantise identically."""
    steps = int(np.rint(angle / RAD_PER_COUNT))
    return (offset + direction * steps) % ENCODER_COUNTS


@dataclass(frozen=True, slots=True)
class EncoderLayout:
    """Mounting of the four encoders: counts at zero angle and sign, in sample order
    (left output, left cam, right output, right cam)."""

    offsets: tuple[int, int, int, int] = (3100, 3100, 12900, 12900)
    directions: tuple[int, int, int, int] = (1, 1, -1, -1)

    def __post_init__(self) -> None:
        for i, (o, d) in enumerate(zip(self.offsets, self.directions, strict=True)):
            if not 0 <= o < ENCODER_COUNTS:
                raise ValueError(f"encoder {i}: offset {o} outside 0..{ENCODER_COUNTS - 1}")
            if d not in (1, -1):
                raise ValueError(f"encoder {i}: direction must be +1 or -1, got {d}")

    def angle(self, index: int, count: int) -> float:
        """Angle in radians of encoder `index` reading `count`, in [-pi, pi)."""
        if not 0 <= count < ENCODER_COUNTS:
            raise ValueError(f"encoder {index}: count {count} outside 0..{ENCODER_COUNTS - 1}")
        return float(count_to_angle(int(count), self.offsets[index], self.directions[index]))

    def count(self, index: int, angle: float) -> int:
        """Inverse of `angle`: the count an ideal encoder reads at `angle` radians."""
        return int(angle_to_count(float(angle), self.offsets[index], self.directions[index]))

    def joint_angles(self, counts: tuple[int, int, int, int]) -> tuple[float, float, float, float]:
        """(theta_left, alpha_left, theta_right, alpha_right): hip flexion from the output
        link, spring deflection as output minus cam."""
        lo, lc, ro, rc = (self.angle(i, c) for i, c in enumerate(counts))
        return lo, lo - lc, ro, ro - rc

    def encode(
        self, theta_left: float, cam_left: float, theta_right: float, cam_right: float
    ) -> tuple[int, int, int, int]:
        """Counts for given output and cam link angles (used by simulators)."""
        return (
            self.count(0, theta_left),
            self.count(1, cam_left),
            self.count(2, theta_right),
            self.count(3, cam_right),
        )


DEFAULT_LAYOUT = EncoderLayout()
