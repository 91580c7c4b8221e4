"""What every controller of the paper does at every 100 Hz tick, around its decision.

Counts to angles (low-level controller), calibration offsets, Kalman velocities and the
trigger, the observation window, the 0.3 s lock hold and the torque estimate. Subclasses
(`UMC`, `EUMC`, `PEC`) supply only `_decide`. A sample that cannot be trusted yields a
flagged tick with no lock: `step` never raises.
"""

from __future__ import annotations

import math
import time
from abc import abstractmethod

from controller.actuator import TorqueModel
from controller.base import Controller
from controller.config import ControllerConfig
from controller.device.base import ENCODER_COUNTS, Sample, Status
from controller.kalman import HipVelocityFilter, VelocityTrigger
from controller.lowlevel import LockHold
from controller.onset import ObservationWindow
from controller.tick import Action, TickFlag, TickRecord

_FAULTS = Status.ENCODER_FAULT | Status.SUPPLY_FAULT
#: Hip flexion outside this range (rad) cannot be a human hip: the sample is bad.
Q_RANGE = (math.radians(-60.0), math.radians(160.0))


class Decision:
    """Scratch for one tick's high-level output (reused, no allocation per tick)."""

    __slots__ = ("action", "detail", "flags", "ran")

    def __init__(self) -> None:
        self.ran = False
        self.action = int(Action.NO_LOCK)
        self.flags = 0
        self.detail: dict[str, float | int | bool] = {}


class PipelineController(Controller):
    """The shared per-tick pipeline; subclasses implement `_decide`."""

    def __init__(self, config: ControllerConfig | None = None) -> None:
        self.config = config or ControllerConfig()
        c = self.config
        self.layout = c.layout
        self.velocity = HipVelocityFilter(accel_std=c.accel_std, meas_std=c.meas_std)
        self.trigger = VelocityTrigger(c.velocity_threshold)
        self.window = ObservationWindow(c.window)
        self.hold = LockHold(c.hold_s)
        self.torque = TorqueModel(c.precompression_pct)
        self.offsets = c.calibration if c.calibration is not None else (0.0, 0.0)
        self.tick_index = 0
        self._decision = Decision()
        self._last_action = int(Action.NO_LOCK)

    def reset(self) -> None:
        """Forget filters, window and held locks."""
        self.velocity.reset()
        self.window.reset()
        self.hold.reset()
        self.tick_index = 0
        self._last_action = int(Action.NO_LOCK)

    @abstractmethod
    def _decide(self, trigger: bool, d: Decision) -> None:
        """Fill `d` for this tick: whether the controller ran, its action and outputs."""

    def _bad(self, sample: Sample, flags: int, t0: float) -> TickRecord:
        # The hold keeps counting so a later good tick resumes the right state, but
        # nothing is commanded on a tick we cannot trust.
        self.hold.update(False, False)
        self.tick_index += 1
        c = sample.counts
        return TickRecord(
            seq=sample.seq,
            t=sample.t if math.isfinite(sample.t) else math.nan,
            t_host=time.time(),
            count_left_output=int(c[0]),
            count_left_cam=int(c[1]),
            count_right_output=int(c[2]),
            count_right_cam=int(c[3]),
            action=int(Action.NO_LOCK),
            flags=flags,
            compute_us=(time.perf_counter() - t0) * 1e6,
            **_truth(sample),
        )

    def step(self, sample: Sample) -> TickRecord:
        """One tick; see the module docstring."""
        t0 = time.perf_counter()
        c = sample.counts
        if not math.isfinite(sample.t) or not all(0 <= x < ENCODER_COUNTS for x in c):
            return self._bad(sample, int(TickFlag.BAD_SAMPLE), t0)
        if sample.status & _FAULTS:
            return self._bad(sample, int(TickFlag.DEVICE_FAULT), t0)
        q_raw_l, alpha_l, q_raw_r, alpha_r = self.layout.joint_angles(c)
        if not (Q_RANGE[0] <= q_raw_l <= Q_RANGE[1] and Q_RANGE[0] <= q_raw_r <= Q_RANGE[1]):
            return self._bad(sample, int(TickFlag.BAD_SAMPLE), t0)
        q_l = q_raw_l - self.offsets[0]
        q_r = q_raw_r - self.offsets[1]
        w_l, w_r = self.velocity.step(q_l, q_r)
        trig = self.trigger(w_l, w_r)
        self.window.push(q_l, q_r)

        d = self._decision
        d.ran = False
        d.flags = 0
        d.detail = {}
        self._decide(trig, d)
        if d.ran:
            self._last_action = d.action
            req_l, req_r = Action(d.action).locks
        else:
            req_l = req_r = False
        lock_l, lock_r = self.hold.update(req_l, req_r)
        self.tick_index += 1

        deadband = self.config.lock_deadband
        locked_l = bool(sample.status & Status.LOCKED_LEFT) or alpha_l > deadband
        locked_r = bool(sample.status & Status.LOCKED_RIGHT) or alpha_r > deadband
        flags = d.flags
        if sample.status & (Status.HARD_STOP_LEFT | Status.HARD_STOP_RIGHT):
            flags |= int(TickFlag.HARD_STOP)
        return TickRecord(
            seq=sample.seq,
            t=sample.t,
            t_host=time.time(),
            count_left_output=c[0],
            count_left_cam=c[1],
            count_right_output=c[2],
            count_right_cam=c[3],
            q_raw_left=q_raw_l,
            q_raw_right=q_raw_r,
            q_left=q_l,
            q_right=q_r,
            omega_left=w_l,
            omega_right=w_r,
            trigger=trig,
            controller_ran=d.ran,
            action=self._last_action,
            lock_left=lock_l,
            lock_right=lock_r,
            locked_left=locked_l,
            locked_right=locked_r,
            alpha_left=alpha_l,
            alpha_right=alpha_r,
            torque_left=self.torque(alpha_l) if locked_l else 0.0,
            torque_right=self.torque(alpha_r) if locked_r else 0.0,
            flags=flags,
            compute_us=(time.perf_counter() - t0) * 1e6,
            **d.detail,  # type: ignore[arg-type]
            **_truth(sample),
        )


def _truth(sample: Sample) -> dict[str, str | int | float]:
    tr = sample.truth
    if tr is None:
        return {}
    return {"truth_activity": tr.activity, "truth_lift": tr.lift_index,
            "truth_progress": tr.progress}

