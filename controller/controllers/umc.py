"""The Utility Maximizing Controller (UMC), its decision step and its registration.

At its rate (10 Hz in the paper), once the observation window is full: Mahalanobis
subsequence DTW of the last 0.3 s against each motion model's online half, chi-square
likelihoods, Bayes posteriors over squat, stoop left, stoop right and other, expected
utilities, arg max. `evaluate` is that evaluation, compiled into the tick; the E-UMC
(`controller.controllers.eumc`) calls it behind its guards.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from controller.config import ControllerConfig, SettingError, ticks_per_run
from controller.controllers.factory import load_models, load_utilities
from controller.controllers.registry import PlanPlace, register
from controller.controllers.spec import ControllerSpec
from controller.decision import expected_utility as decision
from controller.decision.expected_utility import LOCK_MARGIN, decide_fast
from controller.decision.utility_function import UtilitySet
from controller.intent.motion_model import ModelSet
from controller.intent.onset import ModelBank, OnsetCriteria, bank_kernel, window_start
from controller.intent.posteriors import IntentEstimator, intent_kernel
from controller.intent.prior_safety import PriorBounds
from controller.kernel.controller import KernelController
from controller.kernel.core import Compiled, Kernel
from controller.kernel.entry_points import entry_points
from controller.kernel.records import BoolArray, FloatArray, IntArray
from controller.kernel.tick import (
    CONTROLLER_ERROR,
    NO_LOCK,
    window_full,
)
from controller.tick_record import MODEL_NAMES


class UMCData(NamedTuple):
    """The UMC's own arrays in the tick: the model bank's (`ModelBank.kernel_arrays`),
    the intent estimator's and the utility table with its expected utilities. They are
    the arrays those Python objects own, so after a tick they hold its results."""

    bank_parameters: FloatArray
    criteria: FloatArray
    scratch: FloatArray
    distance: FloatArray
    ints: IntArray
    progress: FloatArray
    accepted: BoolArray
    priors: FloatArray
    p_obs: FloatArray
    post: FloatArray
    table: FloatArray
    eu: FloatArray


@njit(cache=True, nogil=True)
def evaluate(window, pos, radius, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """Run the UMC on the window (`state.window`, `state.window_pos`): (ran, action,
    flags), filling the row's model fields."""
    prm, crit, acc, dist, ints, prog, ok, priors, p_obs, post, table, eu = data
    size = window.shape[0] // 2
    obs = window[window_start(size, pos) : pos[0] + size]
    if bank_kernel(obs, prm, radius, crit, acc, dist, ints, prog, ok) != 0:
        return False, NO_LOCK, CONTROLLER_ERROR  # a NaN in the window; not from counts
    intent_kernel(dist, ints[0], ok, priors, p_obs, post)
    equal = priors[0] == priors[1] and priors[1] == priors[2] and priors[2] == priors[3]
    action = decide_fast(table, prog[1], post, eu, 0.0 if equal else LOCK_MARGIN)
    row.d_squat = dist[0]
    row.d_stoop_left = dist[1]
    row.d_stoop_right = dist[2]
    row.l_squat = ints[0, 0]
    row.l_stoop_left = ints[0, 1]
    row.l_stoop_right = ints[0, 2]
    row.s_start_squat = prog[0, 0]
    row.s_start_stoop_left = prog[0, 1]
    row.s_start_stoop_right = prog[0, 2]
    row.s_curr_squat = prog[1, 0]
    row.s_curr_stoop_left = prog[1, 1]
    row.s_curr_stoop_right = prog[1, 2]
    row.accepted_squat = 1.0 if ok[0] else 0.0
    row.accepted_stoop_left = 1.0 if ok[1] else 0.0
    row.accepted_stoop_right = 1.0 if ok[2] else 0.0
    row.p_obs_squat = p_obs[0]
    row.p_obs_stoop_left = p_obs[1]
    row.p_obs_stoop_right = p_obs[2]
    row.post_squat = post[0]
    row.post_stoop_left = post[1]
    row.post_stoop_right = post[2]
    row.post_other = post[3]
    row.eu_no_lock = eu[0]
    row.eu_lock_both = eu[1]
    row.eu_lock_right = eu[2]
    row.eu_lock_left = eu[3]
    return True, action, 0


@njit(cache=True, nogil=True)
def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """The UMC's decision step: evaluate every `divider` ticks once the window is full."""
    s = state.settings[0]
    if window_full(state) and state.phase[0].tick % s.divider == 0:
        return evaluate(state.window, state.window_pos, s.radius, data, row)
    return False, NO_LOCK, 0


COMPILED = entry_points(decide)


class UMC(KernelController):
    """Utility Maximizing Controller over a model set and a utility set."""

    name = "umc"

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None,
        *, compiled: Compiled = COMPILED, rate_hz: float | None = None,
    ) -> None:
        """`compiled` and `rate_hz` (default `umc_rate_hz`) let a variant (the E-UMC) run
        its own decision step at its own rate over the same model bank and utilities."""
        c = config or ControllerConfig()
        ordered = {m.name: m for m in models.ordered()}
        missing = [n for n in MODEL_NAMES if n not in ordered]
        if missing:
            raise ValueError(f"model set {models.version!r} lacks models {missing}")
        self.models = models
        self.utilities = utilities
        self.bank = ModelBank(
            np.stack([ordered[n].online_mean for n in MODEL_NAMES]),
            np.stack([ordered[n].online_cov for n in MODEL_NAMES]),
            band=c.band,
            criteria=OnsetCriteria(s_req=c.s_req, t_req=c.t_req, d_max=c.d_max),
            max_window=c.window,
        )
        if self.bank.max_window < c.window:
            raise ValueError(f"model bank window {self.bank.max_window} < window {c.window}")
        self.table = np.ascontiguousarray(utilities.table.values, dtype=np.float64)
        unsafe = PriorBounds.for_table(self.table).violation(c.priors)
        if unsafe is not None:
            raise SettingError("priors", f"{list(c.priors)} could make the controller lock "
                               f"where equal priors would not ({unsafe}); see "
                               "docs/personalisation.md")
        self.intent = IntentEstimator(np.asarray(c.priors))
        self.eu = np.zeros(4)
        i = self.intent
        data = UMCData(*self.bank.kernel_arrays(), i.priors, i.p_obs, i.post, self.table,
                       self.eu)
        divider = ticks_per_run(c.umc_rate_hz if rate_hz is None else rate_hz)
        kernel = Kernel(c, compiled, divider, data, self.bank.radius)
        super().__init__(c, kernel)

    def warm_up(self) -> None:
        """Compile the tick, and the Python-callable DTW, probabilities and decision."""
        self.bank.warm_up()
        self.intent.warm_up()
        decision.warm_up()
        super().warm_up()


@register("umc", needs_models=True, estimates_intent=True, label="UMC", colour="#1f77b4",
          marker="s", plan=PlanPlace(rank=0))
def build(spec: ControllerSpec) -> UMC:
    """The UMC of a specification."""
    return UMC(load_models(spec), load_utilities(spec), spec.settings)
