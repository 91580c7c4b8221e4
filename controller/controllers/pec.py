"""The Passive Exoskeleton Controller (PEC), its decision step and its registration.

A passive device with a passive torque generator, emulated: it locks both sides
whenever both hips flex at >= 1 rad/s (the paper's trigger), so walking, where the hips
move in anti-phase, stays free. Evaluated every `divider` ticks (100 Hz by default).
"""

from __future__ import annotations

from numba import njit

from controller.config import ControllerConfig, ticks_per_run
from controller.controllers.registry import PlanPlace, register
from controller.controllers.spec import ControllerSpec
from controller.kernel.controller import KernelController
from controller.kernel.core import Kernel
from controller.kernel.entry_points import entry_points
from controller.kernel.tick import LOCK_BOTH, NO_LOCK


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """Lock both while the trigger holds, at the PEC's rate."""
    if state.phase[0].tick % state.settings[0].divider == 0:
        return True, LOCK_BOTH if row.trigger != 0.0 else NO_LOCK, 0
    return False, NO_LOCK, 0


COMPILED = entry_points(decide)


class PEC(KernelController):
    """Lock both while the velocity trigger holds; evaluated at `pec_rate_hz`."""

    name = "pec"

    def __init__(self, config: ControllerConfig | None = None) -> None:
        c = config or ControllerConfig()
        super().__init__(c, Kernel(c, COMPILED, ticks_per_run(c.pec_rate_hz)))


@register("pec", label="PEC", colour="#ff7f0e", marker="o", plan=PlanPlace(rank=2))
def build(spec: ControllerSpec) -> PEC:
    """The PEC of a specification."""
    return PEC(spec.settings)
