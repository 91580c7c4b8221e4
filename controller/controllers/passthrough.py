"""Recording mode (the controller "none"): angles in, no locks out.

Used while demonstrations are recorded and whenever no controller is active. It still
converts counts to angles and reports the mechanism state so that the record is complete,
and flags implausible samples like every controller (`controller.lowlevel.plausibility`), so
recordings show them too; their angles are kept, as nothing is decided on them.
"""

from __future__ import annotations

import math
import time

from controller.controllers.registry import register
from controller.controllers.spec import ControllerSpec
from controller.device.base import ENCODER_COUNTS, Sample, Status
from controller.interface import Controller
from controller.kernel.check import SampleChecker
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.tick_record import Action, TickFlag, TickRecord

# The status bits as plain integers: `Status` operators run Python code per call.
_FAULT = int(Status.ENCODER_FAULT | Status.SUPPLY_FAULT)
_LOCKED_LEFT = int(Status.LOCKED_LEFT)
_LOCKED_RIGHT = int(Status.LOCKED_RIGHT)
_NO_LOCK = int(Action.NO_LOCK)


class PassThroughController(Controller):
    """Never locks. Every tick carries the angles and deflections of both sides."""

    name = "none"

    def __init__(self, layout: EncoderLayout = DEFAULT_LAYOUT) -> None:
        self.layout = layout
        self.checker = SampleChecker()

    def reset(self) -> None:
        """Forget the plausibility reference (nothing else is kept)."""
        self.checker.reset()

    def step(self, sample: Sample) -> TickRecord:
        """Convert the sample; flag it if it is unusable. One record per tick, built
        once its values are known (a record is 55 fields: copying one per tick was
        most of this step's cost)."""
        t0 = time.perf_counter()
        t_host = time.time()
        c = sample.counts
        status = int(sample.status)
        truth = sample.truth
        flags = TickFlag.DEVICE_FAULT if status & _FAULT else TickFlag.NONE
        ql = qr = al = ar = math.nan
        plausibility = 0
        if any(not (0 <= x < ENCODER_COUNTS) for x in c) or not math.isfinite(sample.t):
            flags |= TickFlag.BAD_SAMPLE
        else:
            ql, al, qr, ar = self.layout.joint_angles(c)
            plausibility = 0 if flags else self.checker.check(sample.t, ql, qr, al, ar)
            if plausibility:
                flags |= TickFlag.IMPLAUSIBLE
        return TickRecord(
            seq=sample.seq,
            t=sample.t,
            t_host=t_host,
            count_left_output=c[0],
            count_left_cam=c[1],
            count_right_output=c[2],
            count_right_cam=c[3],
            q_raw_left=ql,
            q_raw_right=qr,
            q_left=ql,
            q_right=qr,
            action=_NO_LOCK,
            locked_left=bool(status & _LOCKED_LEFT),
            locked_right=bool(status & _LOCKED_RIGHT),
            alpha_left=al,
            alpha_right=ar,
            flags=int(flags),
            plausibility=plausibility,
            compute_us=(time.perf_counter() - t0) * 1e6,
            truth_activity=truth.activity if truth else "",
            truth_lift=truth.lift_index if truth else -1,
            truth_progress=truth.progress if truth else math.nan,
        )


@register("none", label="none", idle=True)
def build(spec: ControllerSpec) -> PassThroughController:
    """Recording mode with the specification's encoder layout."""
    return PassThroughController(spec.settings.layout)
