"""The solenoids' duty-cycle budget for bring-up steps that energise them.

The lab's solenoids (RS PRO 177-0139, 12 V, one per side) are intermittent-duty parts:
their coil heats while energised and must cool between pulses. The budget below keeps
every on/off cycle of one coil at or under `MAX_DUTY` (25 %): after a coil was on for
`d` seconds, it must stay off for `d * (1 - MAX_DUTY) / MAX_DUTY` (3 d) before the next
step may energise it. A pulse is at most 0.3 s, so at most one 300 ms pulse per 1.2 s;
no single step energises a coil for more than `MAX_ON_S`. Ten 300 ms pulses asked for in
3.9 s (76 %) get three through (23 %). The budget lives in the server that owns the
device (bring-up steps run one at a time there); a restart of the server takes longer
than any cool-down.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: Highest on-time fraction of one coil over each on/off cycle (docs/hardware-bringup.md).
MAX_DUTY = 0.25
#: Longest single energisation a step may plan (the hardware release test's worst
#: case: 0.3 s to see the solenoid on, then 0.5 s waiting for the drivers to be cut).
MAX_ON_S = 0.8
SIDES = ("left", "right")


class SolenoidDuty:
    """When each side's coil was last released and how long it was on before."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        #: side -> (released at, on for) of its latest energisation
        self.last: dict[str, tuple[float, float]] = {}

    def wait_s(self, side: str) -> float:
        """Seconds until `side` may be energised again (0: now)."""
        if side not in SIDES:
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        if side not in self.last:
            return 0.0
        released, on_s = self.last[side]
        cool = on_s * (1.0 - MAX_DUTY) / MAX_DUTY
        return max(0.0, released + cool - self.clock())

    def refusal(self, side: str) -> str:
        """Why `side` may not be energised now ("" if it may)."""
        wait = self.wait_s(side)
        if wait <= 0.0:
            return ""
        _, on_s = self.last[side]
        return (f"the {side} solenoid is cooling down: it was on for {1000 * on_s:.0f} ms "
                f"and may be energised again in {wait:.1f} s (duty cycle at most "
                f"{100 * MAX_DUTY:.0f} %: off for 3 times its on-time)")

    def record(self, side: str, on_s: float) -> None:
        """`side` was energised for `on_s` seconds, released now."""
        if on_s > 0.0:
            self.last[side] = (self.clock(), min(on_s, MAX_ON_S))
