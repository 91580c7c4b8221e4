"""The simulated wearer's activity labels: the ground truth a recording's `activity`
column holds (an index into `ACTIVITIES`), and which of them are lifts and which gait.

Apart from the generators in `controller.sim.activities` (SciPy splines) so that the
evaluation can read the labels without importing the simulator.
"""

from __future__ import annotations

ACTIVITIES: tuple[str, ...] = (
    "stand",
    "squat",
    "stoop_left",
    "stoop_right",
    "walk",
    "turn",
    "stairs_up",
    "stairs_down",
)
ACTIVITY_CODE: dict[str, int] = {name: i for i, name in enumerate(ACTIVITIES)}
LIFT_KINDS: tuple[str, str, str] = ("squat", "stoop_left", "stoop_right")
GAIT_KINDS: tuple[str, ...] = ("walk", "turn", "stairs_up", "stairs_down")
