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
from controller.kernel import Compiled, Kernel, KernelController
from controller.kernel.tick import NO_LOCK, begin, finish, replay_sample
from controller.registry import PlanPlace, register
from controller.spec import ControllerSpec


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """Run at every tick, never lock, report the constant estimate."""
    row.post_other = data[0]
    rest = (1.0 - data[0]) / 3.0
    row.post_squat = rest
    row.post_stoop_left = rest
    row.post_stoop_right = rest
    return True, NO_LOCK, 0


@njit(cache=True, nogil=True)
def step(state, data, c0, c1, c2, c3, t, status, rows) -> None:  # type: ignore[no-untyped-def]
    """One live tick with this decision (`controller.kernel.tick`)."""
    if begin(state, c0, c1, c2, c3, t, status, rows, 0):
        finish(state, decide(state, data, rows[0]), status, rows, 0)


@njit(cache=True, nogil=True)
def batch(state, data, plant, plant_k, layout, t, q, rows, counts, statuses) -> None:  # type: ignore[no-untyped-def]
    """The batch replay with this decision (`controller.kernel.tick`)."""
    for k in range(t.shape[0]):
        c0, c1, c2, c3, status = replay_sample(plant, plant_k, layout, q, rows, counts,
                                               statuses, k)
        if begin(state, c0, c1, c2, c3, t[k], status, rows, k):
            finish(state, decide(state, data, rows[k]), status, rows, k)


COMPILED = Compiled(step, batch)


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
