"""The Utility Maximizing Controller (UMC) and its extension (E-UMC).

UMC, at its rate (10 Hz in the paper): Mahalanobis subsequence DTW of the last 0.3 s
against each motion model's online half, chi-square likelihoods, Bayes posteriors over
squat, stoop left, stoop right and other, expected utilities, arg max.

E-UMC: the same, with two guards. It needs a calibration (offsets from standing still)
and refuses to lock without one. It runs the UMC only while the velocity trigger holds
(both hips flexing at >= 1 rad/s): at the trigger's rising edge and then at its
triggered rate. Otherwise it decides "no lock" without evaluating anything.

Both run inside the compiled tick (`controller.tick_kernel`, modes `MODE_UMC` and
`MODE_EUMC`) on this module's model bank, priors and utility table.
"""

from __future__ import annotations

import numpy as np

from controller import decision
from controller.config import ControllerConfig, ticks_per_run
from controller.intent import IntentEstimator
from controller.motion_model import ModelSet
from controller.onset import ModelBank, OnsetCriteria
from controller.pipeline import PipelineController
from controller.tick import MODEL_NAMES
from controller.tick_kernel import MODE_EUMC, MODE_UMC, Decider, TickCore
from controller.utilities import UtilitySet


class UMC(PipelineController):
    """Utility Maximizing Controller over a model set and a utility set."""

    name = "umc"
    mode = MODE_UMC

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
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
        self.intent = IntentEstimator(np.asarray(c.priors))
        self.table = np.ascontiguousarray(utilities.table.values, dtype=np.float64)
        self.eu = np.zeros(4)
        self.divider = self._divider(c)
        super().__init__(c)

    @staticmethod
    def _divider(c: ControllerConfig) -> int:
        return ticks_per_run(c.umc_rate_hz)

    def _make_core(self) -> TickCore:
        i = self.intent
        return TickCore(self.config, self.mode, self.divider,
                        Decider(self.bank, i.priors, i.p_obs, i.post, self.table, self.eu))

    def warm_up(self) -> None:
        """Compile the tick, and the Python-callable DTW, probabilities and decision."""
        self.bank.warm_up()
        self.intent.warm_up()
        decision.warm_up()
        super().warm_up()


class EUMC(UMC):
    """Extended UMC: calibration and the velocity trigger in front of the UMC."""

    name = "eumc"
    mode = MODE_EUMC

    def __init__(
        self, models: ModelSet, utilities: UtilitySet, config: ControllerConfig | None = None
    ) -> None:
        super().__init__(models, utilities, config)
        self.calibrated = self.config.calibration is not None

    @staticmethod
    def _divider(c: ControllerConfig) -> int:
        return ticks_per_run(c.eumc_triggered_rate_hz)
