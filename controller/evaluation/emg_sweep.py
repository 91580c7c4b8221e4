"""The paper's open question as a model prediction: spring settings against muscle activity.

The paper ends on how much the exoskeleton lowers muscle activity, and says a gait-lab
EMG study should set the optimal peak torque. Before a lab runs that study, the virtual
cohort can predict its outcome over the two settings the hardware offers: the springs'
precompression (`ControllerConfig.precompression_pct`, the MACCEPA's pretension) and
their stiffness (`MaccepaParams.stiffness_n_per_mm`, two springs of 33.6 N/mm in the
prototype). For every setting and controller it reports the peak support torque and
the reduction of muscle activation. **A model prediction, not a measurement.**

How (per precompression, per virtual participant, per controller):
- the participant's lift trial (`paper-evaluation`, each controller its own repetition,
  as in `controller.evaluation.cohort`) replayed through the controller at that
  precompression, with utilities computed for it (the E-UMC calibrated as there);
- the exoskeleton's torque at another stiffness is the replay's torque times
  `k / k_paper`: the MACCEPA's force is `k (P + elongation)` and the deflection at the
  22 mm stop does not depend on `k` (`controller.lowlevel.actuator`; a test checks the
  proportionality). Assumption, stated: the controllers decide with the prototype's
  spring model (their utilities are those of the paper's springs at that
  precompression); a lab fitting other springs would recompute the utilities
  (`compute_utilities` takes the spring parameters), which may shift lock decisions;
- activation truth (`controller.sim.muscles.MuscleModel`) with that torque and with no
  torque on the *same* movement: the reduction is the device's effect alone, free of
  trial-to-trial movement differences (paired on the trajectory);
- per lift: the peak torque (mean of both sides), and each muscle's mean and peak
  activation (both sides averaged); per participant the mean over lifts; over
  participants the mean with its 95 % t interval.

Ranges: precompression 0, 10, 25 and 50 % (the values `docs/hardware.md` works out;
the controller accepts 0-100 %, and beyond 50 % the spring's travel ends before 62 deg
of deflection); stiffness 0.5x to 2x the prototype's (an assumption: compression
springs of the same size come in about that range of rates).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from controller.config import ControllerConfig
from controller.controllers import registry
from controller.controllers.factory import make_from_spec, needs_models
from controller.controllers.spec import ControllerSpec
from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import (
    SEED_BASE,
    calibrated,
    cohort_controllers,
    default_model_set,
    default_utilities,
)
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import lifts_from_truth
from controller.evaluation.muscle_activity import lift_trial
from controller.evaluation.muscle_stats import mean_t_interval
from controller.evaluation.output_folder import OutputFolder, json_ready
from controller.evaluation.rendering import controller_colour, new_figure, render_figure
from controller.evaluation.study import controller_label
from controller.evaluation.tables import Table
from controller.intent.motion_model import ModelSet
from controller.lowlevel.actuator import PAPER_ACTUATOR
from controller.runner.replay import replay_columns
from controller.sim.muscles import CHANNELS, MUSCLES, MuscleModel
from controller.sim.participant import VirtualParticipant

PRECOMPRESSIONS: tuple[float, ...] = (0.0, 10.0, 25.0, 50.0)
STIFFNESS_FACTORS: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0)
#: Sweep participants are their own seeds, away from the cohort's and the demonstrators'.
SWEEP_SEED_OFFSET = 500_000
PREDICTION = ("MODEL PREDICTION: activation from a static sagittal muscle model driven by "
              "simulated hip moments minus the simulated exoskeleton torque; not a "
              "measurement. It says which setting a lab study should test first, not what "
              "it will find.")
#: The muscles the figure shows: two extensors the study is about, and the hip flexor
#: that shows over-support (negative reduction).
SHOWN = ("erector_spinae_lumbar", "gluteus_maximus", "rectus_femoris")


@dataclass(frozen=True)
class SweepConfig:
    """What to sweep."""

    participants: int = 10
    seed: int = 1
    controllers: tuple[str, ...] = field(default_factory=cohort_controllers)
    precompressions: tuple[float, ...] = PRECOMPRESSIONS
    stiffness_factors: tuple[float, ...] = STIFFNESS_FACTORS
    script: str = "paper-evaluation"

    def __post_init__(self) -> None:
        if not 2 <= self.participants <= 1000:
            raise ValueError(f"participants: must be within 2..1000, got {self.participants}")
        known = cohort_controllers()
        bad = [c for c in self.controllers if c not in known]
        if bad or not self.controllers:
            raise ValueError(f"controllers: choose from {','.join(known)}, got "
                             f"{','.join(self.controllers) or 'none'}")
        if not self.precompressions or any(not 0.0 <= p <= 100.0
                                           for p in self.precompressions):
            raise ValueError(f"precompressions: each within 0..100 %, got "
                             f"{list(self.precompressions)}")
        if not self.stiffness_factors or any(not 0.1 <= k <= 5.0
                                             for k in self.stiffness_factors):
            raise ValueError(f"stiffness factors: each within 0.1..5 of the prototype's, "
                             f"got {list(self.stiffness_factors)}")

    def participant_seed(self, j: int) -> int:
        """Simulator seed of participant j."""
        return SEED_BASE + SWEEP_SEED_OFFSET + self.seed * 1000 + j


@dataclass(frozen=True)
class SweepRow:
    """One setting and controller over the participants (mean, 95 % t interval)."""

    precompression_pct: float
    stiffness_n_per_mm: float
    stiffness_factor: float
    controller: str
    n: int
    peak_torque_nm: tuple[float, float, float]
    #: muscle -> (mean, low, high) reduction of the mean activation over a lift, %
    mean_reduction_pct: dict[str, tuple[float, float, float]]
    #: muscle -> (mean, low, high) reduction of the peak activation in a lift, %
    peak_reduction_pct: dict[str, tuple[float, float, float]]


def _muscle_means(act: np.ndarray) -> dict[str, float]:
    """Both sides' mean, per muscle, of per-channel values (CHANNELS order)."""
    col = {ch: i for i, ch in enumerate(CHANNELS)}
    return {m: float(np.mean([act[col[(m, s)]] for s in ("left", "right")])) for m in MUSCLES}


def participant_values(cfg: SweepConfig, j: int, precompression: float, models: ModelSet,
                       utilities: UtilitySet) -> dict[tuple[str, float], dict[str, Any]]:
    """(controller, stiffness factor) -> per-participant means over lifts: peak torque
    and each muscle's mean and peak activation with and without the exoskeleton."""
    seed = cfg.participant_seed(j)
    p = VirtualParticipant.from_seed(seed)
    model = MuscleModel.for_participant(p)
    settings = ControllerConfig(precompression_pct=precompression)
    start = models.start_posture()
    docs = (models.to_json(), utilities.to_json())
    out: dict[tuple[str, float], dict[str, Any]] = {}
    for i, name in enumerate(cfg.controllers):
        rec, human = lift_trial(p, seed, cfg.script, i)
        s = calibrated(settings, rec, start)[0] if registry.needs_calibration(name) \
            else settings
        sets = needs_models(name)
        spec = ControllerSpec(name, s, models=docs[0] if sets else None,
                              utilities=docs[1] if sets else None)
        cols = TickData.of(replay_columns(rec, make_from_spec(spec), precompression))
        lifts = lifts_from_truth(cols)
        torque = np.nan_to_num(np.column_stack([cols.float_("torque_left"),
                                                cols.float_("torque_right")]))
        free = model.activation(human, np.zeros_like(human))
        for k in cfg.stiffness_factors:
            act = model.activation(human, k * torque)
            peak_t, mean_a, mean_0, peak_a, peak_0 = [], [], [], [], []
            for lf in lifts:
                w = slice(lf.start, lf.end + 1)
                peak_t.append(float(np.mean(k * torque[w].max(axis=0))))
                mean_a.append(act[w].mean(axis=0))
                mean_0.append(free[w].mean(axis=0))
                peak_a.append(act[w].max(axis=0))
                peak_0.append(free[w].max(axis=0))
            out[(name, k)] = {
                "peak_torque_nm": float(np.mean(peak_t)) if peak_t else math.nan,
                "mean": _muscle_means(np.mean(mean_a, axis=0)),
                "mean_free": _muscle_means(np.mean(mean_0, axis=0)),
                "peak": _muscle_means(np.mean(peak_a, axis=0)),
                "peak_free": _muscle_means(np.mean(peak_0, axis=0)),
            }
    return out


def _interval(x: Sequence[float]) -> tuple[float, float, float]:
    mean, lo, hi, _p = mean_t_interval([v for v in x if math.isfinite(v)])
    return mean, lo, hi


def run_sweep(cfg: SweepConfig, models: ModelSet | None = None,
              utilities: Callable[[float], UtilitySet] | None = None,
              log: Callable[[str], None] = print) -> list[SweepRow]:
    """Every precompression x stiffness x controller over the participants."""
    models = models if models is not None else default_model_set()
    make_utilities = utilities or default_utilities
    rows: list[SweepRow] = []
    for pct in cfg.precompressions:
        log(f"precompression {pct:g} %: utilities, then {cfg.participants} participants")
        us = make_utilities(pct)
        per = [participant_values(cfg, j, pct, models, us) for j in range(cfg.participants)]
        for name in cfg.controllers:
            for k in cfg.stiffness_factors:
                vals = [v[(name, k)] for v in per]

                def red(kind: str, muscle: str, vals: list[dict[str, Any]] = vals
                        ) -> tuple[float, float, float]:
                    return _interval([100.0 * (1.0 - v[kind][muscle] / v[f"{kind}_free"][muscle])
                                      for v in vals])

                rows.append(SweepRow(
                    pct, k * PAPER_ACTUATOR.stiffness_n_per_mm, k, name, len(vals),
                    _interval([v["peak_torque_nm"] for v in vals]),
                    {m: red("mean", m) for m in MUSCLES},
                    {m: red("peak", m) for m in MUSCLES}))
    return rows


def table(rows: Sequence[SweepRow]) -> Table:
    """One line per setting and controller: torque and the extensors' reductions."""
    out = []
    for r in rows:
        cells: list[Any] = [r.precompression_pct, r.stiffness_n_per_mm, r.controller, r.n,
                            *r.peak_torque_nm]
        for m in MUSCLES:
            cells += [r.mean_reduction_pct[m][0], r.mean_reduction_pct[m][1],
                      r.mean_reduction_pct[m][2], r.peak_reduction_pct[m][0]]
        out.append(tuple(cells))
    header = ["precompression_pct", "stiffness_n_per_mm", "controller", "n",
              "peak_torque_nm", "peak_torque_ci95_low", "peak_torque_ci95_high"]
    for m in MUSCLES:
        header += [f"{m}_mean_reduction_pct", f"{m}_mean_reduction_ci95_low",
                   f"{m}_mean_reduction_ci95_high", f"{m}_peak_reduction_pct"]
    return Table(tuple(header), tuple(out), float_format=".1f",
                 title="Spring settings against muscle activation (MODEL PREDICTION)",
                 notes=("Peak torque: per lift the peak exoskeleton torque, mean of both "
                        "sides; per participant the mean over lifts. Reduction: 100 (1 - "
                        "activation with the exoskeleton / without) on the same movement, "
                        "both sides averaged; mean over participants with its 95 % t "
                        "interval. Negative: more activity (for the flexors: the springs "
                        "giving more than the movement needs).", PREDICTION))


def summary_markdown(rows: Sequence[SweepRow]) -> str:
    """A compact table: the lumbar erector spinae's mean reduction per setting."""
    ctls = list(dict.fromkeys(r.controller for r in rows))
    lines = ["| precompression | stiffness (N/mm) | "
             + " | ".join(f"{controller_label(c)}: peak torque (Nm) / lumbar ES reduction (%)"
                          for c in ctls) + " |",
             "| --- | --- |" + " --- |" * len(ctls)]
    settings = list(dict.fromkeys((r.precompression_pct, r.stiffness_n_per_mm) for r in rows))
    by = {(r.precompression_pct, r.stiffness_n_per_mm, r.controller): r for r in rows}
    for pct, k in settings:
        cells = []
        for c in ctls:
            r = by[(pct, k, c)]
            m = r.mean_reduction_pct["erector_spinae_lumbar"]
            cells.append(f"{r.peak_torque_nm[0]:.1f} / {m[0]:.1f} [{m[1]:.1f}, {m[2]:.1f}]")
        lines.append(f"| {pct:g} % | {k:.1f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def figure(rows: Sequence[SweepRow]) -> tuple[bytes, bytes]:
    """Reduction of the shown muscles against peak support torque, per controller;
    points of one precompression joined across stiffness."""
    fig = new_figure(10.5, 3.6)
    ctls = list(dict.fromkeys(r.controller for r in rows))
    pcts = list(dict.fromkeys(r.precompression_pct for r in rows))
    markers = "osD^v<>"
    for i, muscle in enumerate(SHOWN):
        ax = fig.add_subplot(1, len(SHOWN), i + 1)
        for ci, c in enumerate(ctls):
            for pi, pct in enumerate(pcts):
                sel = sorted((r for r in rows if r.controller == c
                              and r.precompression_pct == pct),
                             key=lambda r: r.stiffness_factor)
                x = [r.peak_torque_nm[0] for r in sel]
                y = [r.mean_reduction_pct[muscle][0] for r in sel]
                ax.plot(x, y, marker=markers[pi % len(markers)], ms=3.5, lw=0.9,
                        color=controller_colour(c, ci),
                        label=f"{controller_label(c)} {pct:g} %")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_xlabel("peak support torque per hip (Nm)", fontsize=7.5)
        ax.set_ylabel("reduction of mean activation (%)", fontsize=7.5)
        ax.set_title(f"{muscle.replace('_', ' ')} (MODEL PREDICTION)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.axes[0].legend(fontsize=5.5, ncol=2, loc="upper left")
    fig.subplots_adjust(left=0.06, right=0.99, top=0.9, bottom=0.14, wspace=0.25)
    r = render_figure(fig)
    return r.png, r.svg


def write_outputs(cfg: SweepConfig, rows: Sequence[SweepRow], out: Path,
                  wall_s: float | None = None) -> list[Path]:
    """sweep.csv/.md, sweep.json, sweep.png/.svg and README.md into `out`."""
    files = OutputFolder(out)
    t = table(rows)
    files.put("sweep.csv", t.to_csv())
    files.put("sweep.md", t.to_markdown())
    png, svg = figure(rows)
    files.put("sweep.png", png)
    files.put("sweep.svg", svg)

    files.put("sweep.json", json.dumps(json_ready({
        "format": "exostudy.emg_sweep", "format_version": 1, "prediction": PREDICTION,
        "config": {**asdict(cfg)}, "paper_stiffness_n_per_mm": PAPER_ACTUATOR.stiffness_n_per_mm,
        "rows": [asdict(r) for r in rows]}), indent=1, allow_nan=False))
    files.put("README.md", "\n".join([
        "# Spring settings against muscle activation (model prediction)", "", PREDICTION, "",
        f"{cfg.participants} virtual participants (seed {cfg.seed}), controllers "
        f"{', '.join(controller_label(c) for c in cfg.controllers)}, script `{cfg.script}`; "
        f"precompression {', '.join(f'{p:g}' for p in cfg.precompressions)} %, stiffness "
        f"{', '.join(f'{k:g}' for k in cfg.stiffness_factors)} x the prototype's "
        f"{PAPER_ACTUATOR.stiffness_n_per_mm:g} N/mm"
        + (f"; {wall_s:.0f} s." if wall_s is not None else "."), "",
        "Per setting and controller: mean peak support torque per hip, and the lumbar "
        "erector spinae's reduction of mean activation over a lift (mean [95 % t "
        "interval]); every muscle in `sweep.md`/`sweep.csv`, method in "
        "docs/muscle-activity.md.", "", summary_markdown(rows)]))
    return files.written
