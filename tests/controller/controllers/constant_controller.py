"""A fourth controller in one module, for the registry tests and the worked example of
`docs/adding-a-controller.md`: it decides "no lock" at every tick and reports a
constant intent estimate: `post_other` is the setting `extra["constant"]` (default
0.5), the three lift models share the rest. It declares that it needs a calibration,
estimates intent and enters a trial plan after the paper's controllers, so it takes
part in a study, a virtual study and a virtual cohort."""

from __future__ import annotations

import numpy as np
from numba import njit

from controller.config import ControllerConfig
from controller.controllers.registry import PlanPlace, register
from controller.controllers.spec import ControllerSpec
from controller.kernel.controller import KernelController
from controller.kernel.core import Kernel
from controller.kernel.entry_points import entry_points
from controller.kernel.tick import NO_LOCK


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """Run at every tick, never lock, report the constant estimate."""
    row.post_other = data[0]
    rest = (1.0 - data[0]) / 3.0
    row.post_squat = rest
    row.post_stoop_left = rest
    row.post_stoop_right = rest
    return True, NO_LOCK, 0


COMPILED = entry_points(decide)


class ConstantController(KernelController):
    """Locks nothing; reports one number."""

    name = "constant"

    def __init__(self, config: ControllerConfig | None = None) -> None:
        c = config or ControllerConfig()
        value = np.array([float(c.extra.get("constant", 0.5))])
        super().__init__(c, Kernel(c, COMPILED, 1, value))


@register("constant", needs_calibration=True, estimates_intent=True, label="Constant",
          colour="#2ca02c", marker="D", plan=PlanPlace(rank=3, counterbalanced=False))
def build(spec: ControllerSpec) -> ConstantController:
    """The constant controller of a specification."""
    return ConstantController(spec.settings)
