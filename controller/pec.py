"""The Passive Exoskeleton Controller (PEC): a passive device with a passive torque
generator, emulated. It locks both sides whenever both hips flex at >= 1 rad/s (the
paper's trigger), so walking, where the hips move in anti-phase, stays free.

It runs inside the compiled tick (`controller.tick_kernel`, mode `MODE_PEC`)."""

from __future__ import annotations

from controller.config import ControllerConfig, ticks_per_run
from controller.pipeline import PipelineController
from controller.tick_kernel import MODE_PEC, TickCore


class PEC(PipelineController):
    """Lock both while the velocity trigger holds; evaluated at `pec_rate_hz`."""

    name = "pec"

    def __init__(self, config: ControllerConfig | None = None) -> None:
        c = config or ControllerConfig()
        self.divider = ticks_per_run(c.pec_rate_hz)
        super().__init__(c)

    def _make_core(self) -> TickCore:
        return TickCore(self.config, MODE_PEC, self.divider)
