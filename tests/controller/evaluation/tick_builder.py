"""Hand-made tick sequences with known answers, built the way the pipeline fills ticks.

A decision sets `controller_ran`, makes `action` the held last decision from that tick
on (as `PipelineController` records it) and holds the solenoid command 30 ticks (0.3 s
at 100 Hz, the low-level hold). Everything else keeps `TickRecord`'s defaults.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from controller.evaluation import Lift, LiftKind
from controller.tick import Action, TickRecord

HOLD_TICKS = 30
DT = 0.01


class TickBuilder:
    """Columns of `n` standing ticks, to be given lifts, gait, decisions and posteriors."""

    def __init__(self, n: int) -> None:
        defaults = TickRecord(seq=0, t=0.0)
        self.n = n
        self.cols: dict[str, np.ndarray[Any, Any]] = {}
        for name, v in zip(TickRecord.field_names(), defaults.as_tuple(), strict=True):
            if isinstance(v, str):
                self.cols[name] = np.array([v] * n, dtype="U16")
            else:
                self.cols[name] = np.array([v] * n)
        self.cols["seq"] = np.arange(n)
        self.cols["t"] = np.arange(n) * DT
        self.cols["truth_activity"][:] = "stand"
        self.cols["torque_left"][:] = 0.0
        self.cols["torque_right"][:] = 0.0

    def lift(self, index: int, kind: LiftKind, start: int, end: int) -> Lift:
        """Mark ticks start..end (inclusive) as lift `index` of `kind` in the truth."""
        s = slice(start, end + 1)
        self.cols["truth_activity"][s] = kind
        self.cols["truth_lift"][s] = index
        self.cols["truth_progress"][s] = np.linspace(0.0, 1.0, end - start + 1)
        return Lift(index, kind, start, end)

    def gait(self, start: int, end: int, activity: str = "walk") -> None:
        """Mark ticks start..end (inclusive) as a gait activity in the truth."""
        self.cols["truth_activity"][start : end + 1] = activity

    def run(self, k: int, action: Action = Action.NO_LOCK) -> None:
        """The controller runs at tick k and decides `action`."""
        self.cols["controller_ran"][k] = True
        self.cols["action"][k:] = int(action)
        left, right = action.locks
        if left:
            self.cols["lock_left"][k : k + HOLD_TICKS] = True
        if right:
            self.cols["lock_right"][k : k + HOLD_TICKS] = True

    def posterior(self, k: int, kind: str, p: float) -> None:
        """At tick k, `kind` has posterior p and the other three share the rest."""
        for cat in ("squat", "stoop_left", "stoop_right", "other"):
            self.cols[f"post_{cat}"][k] = p if cat == kind else (1.0 - p) / 3.0

    def torque(self, k: int, left: float, right: float) -> None:
        """Exoskeleton torques at tick k."""
        self.cols["torque_left"][k] = left
        self.cols["torque_right"][k] = right

    def columns(self) -> dict[str, np.ndarray[Any, Any]]:
        """A copy of the columns."""
        return {k: v.copy() for k, v in self.cols.items()}
