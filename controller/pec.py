"""The Passive Exoskeleton Controller (PEC): a passive device with a passive torque
generator, emulated. It locks both sides whenever both hips flex at >= 1 rad/s (the
paper's trigger), so walking, where the hips move in anti-phase, stays free."""

from __future__ import annotations

from controller.config import ControllerConfig, ticks_per_run
from controller.pipeline import Decision, PipelineController
from controller.tick import Action


class PEC(PipelineController):
    """Lock both while the velocity trigger holds; evaluated at `pec_rate_hz`."""

    name = "pec"

    def __init__(self, config: ControllerConfig | None = None) -> None:
        super().__init__(config)
        self.divider = ticks_per_run(self.config.pec_rate_hz)

    def _decide(self, trigger: bool, d: Decision) -> None:
        if self.tick_index % self.divider != 0:
            return
        d.ran = True
        d.action = int(Action.LOCK_BOTH if trigger else Action.NO_LOCK)
