"""The Passive Exoskeleton Controller (PEC), its decision step and its registration.

A passive device with a passive torque generator, emulated: it locks both sides
whenever both hips flex at >= 1 rad/s (the paper's trigger), so walking, where the hips
move in anti-phase, stays free. Evaluated every `divider` ticks (100 Hz by default).
"""

from __future__ import annotations

from numba import njit

from controller.config import ControllerConfig, ticks_per_run
from controller.kernel import Compiled, Kernel, KernelController
from controller.kernel.tick import LOCK_BOTH, NO_LOCK, begin, finish, replay_sample
from controller.registry import PlanPlace, register
from controller.spec import ControllerSpec


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """Lock both while the trigger holds, at the PEC's rate."""
    if state.phase[0].tick % state.settings[0].divider == 0:
        return True, LOCK_BOTH if row.trigger != 0.0 else NO_LOCK, 0
    return False, NO_LOCK, 0


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
