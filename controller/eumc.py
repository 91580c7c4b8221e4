"""The extended UMC (E-UMC): the UMC behind two guards, and its registration.

It needs a calibration (offsets from standing still) and refuses to lock without one.
It runs the UMC only while the velocity trigger holds (both hips flexing at >= 1 rad/s):
at the trigger's rising edge and then every `divider` triggered ticks (10 Hz in the
paper). Otherwise it decides "no lock" at every tick without evaluating anything.
"""

from __future__ import annotations

from numba import njit

from controller.config import ControllerConfig, ticks_per_run
from controller.factory import load_models, load_utilities
from controller.kernel import Compiled
from controller.kernel.tick import (
    NO_LOCK,
    NOT_CALIBRATED,
    begin,
    finish,
    replay_sample,
    window_full,
)
from controller.motion_model import ModelSet
from controller.registry import PlanPlace, register
from controller.spec import ControllerSpec
from controller.umc import UMC, evaluate
from controller.utilities import UtilitySet


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


class EUMC(UMC):
    """Extended UMC: calibration and the velocity trigger in front of the UMC."""

    name = "eumc"

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
        super().__init__(models, utilities, config)
        self.calibrated = self.config.calibration is not None

    @staticmethod
    def _compiled() -> Compiled:
        return COMPILED

    @staticmethod
    def _divider(c: ControllerConfig) -> int:
        return ticks_per_run(c.eumc_triggered_rate_hz)


@register("eumc", needs_models=True, needs_calibration=True, estimates_intent=True,
          label="E-UMC", colour="#9467bd", marker="^",
          plan=PlanPlace(rank=1, counterbalanced=False, optional=True))
def build(spec: ControllerSpec) -> EUMC:
    """The E-UMC of a specification."""
    return EUMC(load_models(spec), load_utilities(spec), spec.settings)
