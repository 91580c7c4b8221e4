"""Hand-made tick sequences with known answers, built the way the pipeline fills ticks.

A decision sets `controller_ran`, makes `action` the held last decision from that tick
on (as `KernelController` records it) and holds the solenoid command 30 ticks (0.3 s
at 100 Hz, the low-level hold). Everything else keeps `TickRecord`'s defaults.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from controller.controllers.pec import PEC
from controller.device.base import LockCommand
from controller.evaluation.lifts import GaitTrial, Lift, LiftKind, lifts_from_truth
from controller.evaluation.study import RecordingEvaluation, evaluate_recording
from controller.interface import Controller
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.tick_record import Action, TickRecord

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


def lifting_recording(
    participant: str, controller: str, good: bool, intent: bool = True
) -> RecordingEvaluation:
    """Two squats and two stoops. With `good`, every lift is recognised and decided
    correctly; otherwise lift 1 (a squat) is unrecognised and missed, lift 2 (stoop
    left) decided wrong and lift 3 (stoop right) unrecognised. Without `intent` no
    posterior is recorded (a PEC)."""
    b = TickBuilder(1000)
    kinds = ("squat", "squat", "stoop_left", "stoop_right")
    lifts = [b.lift(i, k, 100 + 200 * i, 199 + 200 * i) for i, k in enumerate(kinds)]  # type: ignore[arg-type]
    for i, lf in enumerate(lifts):
        if intent and (good or i in (0, 2)):
            b.posterior(lf.start + 20, lf.kind, 0.9)
        if good or i in (0, 3):
            b.run(lf.start + 30, lf.correct_action)
        elif i == 2:
            b.run(lf.start + 30, Action.LOCK_BOTH)
        b.torque(lf.start + 60, 10.0 + i, 20.0 + i)
    cols = b.columns()
    return evaluate_recording(cols, participant, controller, lifts_from_truth(cols))


def gait_recording(participant: str, controller: str, locks: int, kind: str) -> RecordingEvaluation:
    b = TickBuilder(2000)
    for j in range(locks):
        b.run(100 + 100 * j, Action.LOCK_RIGHT)
    return evaluate_recording(
        b.columns(), participant, controller, trials=[GaitTrial(kind, 0, 1999)]  # type: ignore[arg-type]
    )


def simulate_pec(script: str, seed: int) -> list[TickRecord]:
    """The PEC on a simulated wearer following `script`, tick by tick."""
    return closed_loop(PEC(), script, seed)


def closed_loop(ctl: Controller, script: str, seed: int) -> list[TickRecord]:
    """`ctl` on a simulated wearer following `script`, each tick's lock command fed
    back to the exoskeleton before the next sample."""
    ctl.warm_up()
    exo = SimulatedExoskeleton(seed=seed, script=script)
    cmd: LockCommand | None = None
    out = []
    while not exo.finished:
        s = exo.tick(cmd)
        r = ctl.step(s)
        out.append(r)
        cmd = LockCommand(s.seq, r.lock_left, r.lock_right)
    return out
