"""The extended UMC (E-UMC): the UMC behind two guards, and its registration.

It needs a calibration (offsets from standing still) and refuses to lock without one.
It runs the UMC only while the velocity trigger holds (both hips flexing at >= 1 rad/s):
at the trigger's rising edge and then every `divider` triggered ticks (10 Hz in the
paper). Otherwise it decides "no lock" at every tick without evaluating anything.
"""

from __future__ import annotations

from numba import njit

from controller.config import ControllerConfig
from controller.controllers.factory import load_models, load_utilities
from controller.controllers.registry import PlanPlace, register
from controller.controllers.spec import ControllerSpec
from controller.controllers.umc import UMC, evaluate
from controller.decision.utility_function import UtilitySet
from controller.intent.motion_model import ModelSet
from controller.kernel.entry_points import entry_points
from controller.kernel.tick import (
    NO_LOCK,
    NOT_CALIBRATED,
    window_full,
)


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """The E-UMC's decision step (see the module docstring)."""
    s = state.settings[0]
    phase = state.phase[0]
    if s.calibrated == 0:
        return False, NO_LOCK, NOT_CALIBRATED
    if row.trigger == 0.0:
        phase.since = -1
        return True, NO_LOCK, 0  # the decision "no lock" is taken at 100 Hz while idle
    phase.since += 1
    if window_full(state) and phase.since % s.divider == 0:
        return evaluate(state.window, state.window_pos, s.radius, data, row)
    return False, NO_LOCK, 0


COMPILED = entry_points(decide)


class EUMC(UMC):
    """Extended UMC: calibration and the velocity trigger in front of the UMC."""

    name = "eumc"

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
        c = config or ControllerConfig()
        super().__init__(models, utilities, c, compiled=COMPILED,
                         rate_hz=c.eumc_triggered_rate_hz)
        self.calibrated = self.config.calibration is not None


@register("eumc", needs_models=True, needs_calibration=True, estimates_intent=True,
          label="E-UMC", colour="#9467bd", marker="^",
          plan=PlanPlace(rank=1, counterbalanced=False, optional=True))
def build(spec: ControllerSpec) -> EUMC:
    """The E-UMC of a specification."""
    return EUMC(load_models(spec), load_utilities(spec), spec.settings)
