"""The Utility Maximizing Controller (UMC) and its extension (E-UMC).

UMC, at its rate (10 Hz in the paper): Mahalanobis subsequence DTW of the last 0.3 s
against each motion model's online half, chi-square likelihoods, Bayes posteriors over
squat, stoop left, stoop right and other, expected utilities, arg max.

E-UMC: the same, with two guards. It needs a calibration (offsets from standing still)
and refuses to lock without one. It runs the UMC only while the velocity trigger holds
(both hips flexing at >= 1 rad/s): at the trigger's rising edge and then at its
triggered rate. Otherwise it decides "no lock" without evaluating anything.
"""

from __future__ import annotations

import numpy as np

from controller import decision
from controller.config import ControllerConfig, ticks_per_run
from controller.intent import IntentEstimator
from controller.motion_model import ModelSet
from controller.onset import ModelBank, OnsetCriteria
from controller.pipeline import Decision, PipelineController
from controller.tick import MODEL_NAMES, Action, TickFlag
from controller.utilities import UtilitySet

_ACTION_FIELDS = ("eu_no_lock", "eu_lock_both", "eu_lock_right", "eu_lock_left")
_POST_FIELDS = tuple(f"post_{m}" for m in (*MODEL_NAMES, "other"))


class UMC(PipelineController):
    """Utility Maximizing Controller over a model set and a utility set."""

    name = "umc"

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
        super().__init__(config)
        c = self.config
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
        self.intent = IntentEstimator(np.asarray(c.priors))
        self.table = utilities.table.values
        self.eu = np.zeros(4)
        self.divider = ticks_per_run(c.umc_rate_hz)

    def warm_up(self) -> None:
        """Compile DTW, probabilities and decision before the loop starts."""
        self.bank.warm_up()
        self.intent.warm_up()
        decision.warm_up()

    def _run_umc(self, d: Decision) -> None:
        bank = self.bank
        bank.evaluate(self.window.view())
        post = self.intent.update(bank.D, bank.L, bank.accepted)
        d.action = int(decision.decide_fast(self.table, bank.s_curr, post, self.eu))
        d.ran = True
        p_obs = self.intent.p_obs
        detail = d.detail
        for j, m in enumerate(MODEL_NAMES):
            detail[f"d_{m}"] = float(bank.D[j])
            detail[f"l_{m}"] = int(bank.L[j])
            detail[f"s_start_{m}"] = float(bank.s_start[j])
            detail[f"s_curr_{m}"] = float(bank.s_curr[j])
            detail[f"accepted_{m}"] = bool(bank.accepted[j])
            detail[f"p_obs_{m}"] = float(p_obs[j])
        for j, f in enumerate(_POST_FIELDS):
            detail[f] = float(post[j])
        for a, f in enumerate(_ACTION_FIELDS):
            detail[f] = float(self.eu[a])

    def _decide(self, trigger: bool, d: Decision) -> None:
        if not self.window.full:
            return
        if self.tick_index % self.divider == 0:
            self._run_umc(d)


class EUMC(UMC):
    """Extended UMC: calibration and the velocity trigger in front of the UMC."""

    name = "eumc"

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
        super().__init__(models, utilities, config)
        self.divider = ticks_per_run(self.config.eumc_triggered_rate_hz)
        self.calibrated = self.config.calibration is not None
        self._since_trigger = -1

    def reset(self) -> None:
        """Also forget the trigger state."""
        super().reset()
        self._since_trigger = -1

    def _decide(self, trigger: bool, d: Decision) -> None:
        if not self.calibrated:
            d.flags |= int(TickFlag.NOT_CALIBRATED)
            return
        if not trigger:
            self._since_trigger = -1
            d.ran = True  # the decision "no lock" is taken at 100 Hz while idle
            d.action = int(Action.NO_LOCK)
            return
        self._since_trigger += 1
        if not self.window.full:
            return
        if self._since_trigger % self.divider == 0:
            self._run_umc(d)
