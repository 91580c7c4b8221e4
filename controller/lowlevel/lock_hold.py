"""The low-level controller's lock hold (`e_k` in the paper).

A solenoid needs time to seat the pawl in the ratchet, so each side's lock command,
once requested, stays on for `hold_s` after the last request (the paper: 0.3 s). At
100 Hz that is 30 ticks: a request at tick k keeps the output on at ticks k..k+29, and
a new request restarts the count. There is no commanded unlock.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from controller.device.base import SAMPLE_PERIOD_S

IntArray = npt.NDArray[np.int64]


@njit("UniTuple(boolean, 2)(int64[::1], int64, boolean, boolean)", cache=True, nogil=True)
def hold_update(
    left_right: IntArray, hold_ticks: int, request_left: bool, request_right: bool
) -> tuple[bool, bool]:
    """Advance the two countdowns `left_right` one tick; return the (left, right) commands.

    The one implementation of the hold: `LockHold` and the compiled control tick
    (`controller.kernel.tick`) both call it.
    """
    if request_left:
        left_right[0] = hold_ticks
    if request_right:
        left_right[1] = hold_ticks
    out_left = left_right[0] > 0
    out_right = left_right[1] > 0
    if out_left:
        left_right[0] -= 1
    if out_right:
        left_right[1] -= 1
    return out_left, out_right


class LockHold:
    """Holds each side's lock request for a fixed number of ticks."""

    def __init__(self, hold_s: float = 0.3, dt: float = SAMPLE_PERIOD_S) -> None:
        """Args: hold_s hold duration, dt tick period, both in seconds (> 0)."""
        if not (math.isfinite(hold_s) and hold_s > 0 and math.isfinite(dt) and dt > 0):
            raise ValueError(f"hold_s and dt must be positive, got {hold_s!r}, {dt!r}")
        self.hold_s = hold_s
        self.dt = dt
        #: Ticks the output stays on after one request (rounded: 0.3 / 0.01 -> 30).
        self.hold_ticks = max(1, round(hold_s / dt))
        #: Ticks left on each side, (left, right); the array `hold_update` counts down.
        self.counters = np.zeros(2, dtype=np.int64)

    def reset(self) -> None:
        """Drop any held command (both sides off at the next tick)."""
        self.counters[:] = 0

    def update(self, request_left: bool, request_right: bool) -> tuple[bool, bool]:
        """Advance one tick with this tick's requests; return the (left, right) commands."""
        return hold_update(self.counters, self.hold_ticks, bool(request_left),
                           bool(request_right))

    @property
    def remaining(self) -> tuple[int, int]:
        """Ticks each side will still be on without a new request, after this tick."""
        return int(self.counters[0]), int(self.counters[1])
