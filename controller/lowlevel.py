"""The low-level controller's lock hold (`e_k` in the paper).

A solenoid needs time to seat the pawl in the ratchet, so each side's lock command,
once requested, stays on for `hold_s` after the last request (hardware.md: 0.3 s). At
100 Hz that is 30 ticks: a request at tick k keeps the output on at ticks k..k+29, and
a new request restarts the count. There is no commanded unlock.
"""

from __future__ import annotations

import math


class LockHold:
    """Holds each side's lock request for a fixed number of ticks."""

    def __init__(self, hold_s: float = 0.3, dt: float = 0.01) -> None:
        """Args: hold_s hold duration, dt tick period, both in seconds (> 0)."""
        if not (math.isfinite(hold_s) and hold_s > 0 and math.isfinite(dt) and dt > 0):
            raise ValueError(f"hold_s and dt must be positive, got {hold_s!r}, {dt!r}")
        self.hold_s = hold_s
        self.dt = dt
        #: Ticks the output stays on after one request (rounded: 0.3 / 0.01 -> 30).
        self.hold_ticks = max(1, round(hold_s / dt))
        self._left = 0
        self._right = 0

    def reset(self) -> None:
        """Drop any held command (both sides off at the next tick)."""
        self._left = 0
        self._right = 0

    def update(self, request_left: bool, request_right: bool) -> tuple[bool, bool]:
        """Advance one tick with this tick's requests; return the (left, right) commands."""
        if request_left:
            self._left = self.hold_ticks
        if request_right:
            self._right = self.hold_ticks
        out_left = self._left > 0
        out_right = self._right > 0
        if out_left:
            self._left -= 1
        if out_right:
            self._right -= 1
        return out_left, out_right

    @property
    def remaining(self) -> tuple[int, int]:
        """Ticks each side will still be on without a new request, after this tick."""
        return self._left, self._right
