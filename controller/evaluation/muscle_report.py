"""Muscle activity of a virtual cohort: reductions, repeated measures, figures, Markdown.

Why a module of its own: the cohort report (`cohort_report`) and the replication report
show the same section, computed once here from the participants' `ParticipantMuscles`
(`controller.evaluation.muscle_activity`) with `controller.evaluation.muscle_stats`.

What is reported, per outcome (peak, mean, iEMG of the MVC-normalised envelope, each a
participant's mean over their lifts):
- the reduction of every condition against each baseline per channel (muscle and side):
  mean per-participant reduction with its 95 % t interval, a one-sample t-test of the
  reductions, Holm-corrected over the channels x conditions of that outcome and
  baseline; beside it the same reduction of the activation truth (the known answer);
- the Friedman test across all conditions per channel;
- figures: the envelope over the normalised lift cycle (mean over participants, band
  +- 1 SD) per condition and muscle, and the reduction per channel and controller with
  its 95 % interval.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from controller.controllers import registry
from controller.evaluation.cohort import Cohort
from controller.evaluation.muscle_activity import LABELS, OUTCOME_UNITS, OUTCOMES
from controller.evaluation.muscle_stats import (
    OutcomeRow,
    Reduction,
    RepeatedMeasures,
    reductions,
    repeated_measures,
)
from controller.evaluation.rendering import controller_colour, new_figure, render_figure
from controller.evaluation.study import controller_label
from controller.evaluation.tables import Table
from controller.sim.muscles import MUSCLES

#: The outcome and baseline the README and the figures lead with.
PRIMARY_OUTCOME = "mean"
PRIMARY_BASELINE = "no_exoskeleton"
SIM_CAVEAT = ("Simulated muscle activity: activation follows the hip and lumbar moments "
              "the simulation computes minus the exoskeleton's torque (a static, "
              "sagittal model without activation dynamics, fatigue or the device's mass; "
              "docs/muscle-activity.md), so these reductions are a model's prediction, "
              "not a measurement.")


@dataclass(frozen=True)
class MuscleAnalysis:
    """Everything computed from a cohort's muscle activity."""

    controllers: tuple[str, ...]
    baselines: tuple[str, ...]
    #: (outcome, baseline) -> reductions from sEMG, and of the activation truth.
    reductions: dict[tuple[str, str], list[Reduction]]
    truth: dict[tuple[str, str], list[Reduction]]
    #: outcome -> Friedman per channel across every condition.
    repeated: dict[str, list[RepeatedMeasures]]

    @property
    def conditions(self) -> tuple[str, ...]:
        """Controllers, then baselines."""
        return (*self.controllers, *self.baselines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (NaN as None)."""
        return {"controllers": list(self.controllers), "baselines": list(self.baselines),
                "reductions": [{"outcome": o, **r.to_dict()}
                               for (o, _b), rs in self.reductions.items() for r in rs],
                "truth_reductions": [{"outcome": o, **r.to_dict()}
                                     for (o, _b), rs in self.truth.items() for r in rs],
                "repeated_measures": [{"outcome": o, **r.to_dict()}
                                      for o, rs in self.repeated.items() for r in rs],
                "caveat": SIM_CAVEAT}


def outcome_rows(cohort: Cohort, outcome: str, task: str = "all",
                 source: str = "emg") -> list[OutcomeRow]:
    """One row per participant, condition and channel: the participant's mean over
    lifts of `outcome` from the sEMG (`source` "emg") or the activation ("truth")."""
    rows = []
    for p in cohort.participants:
        if p.muscles is None:
            continue
        for cond, c in p.muscles.conditions.items():
            values = (c.emg if source == "emg" else c.truth).get(task, {}).get(outcome, {})
            rows += [OutcomeRow(f"V{p.index + 1:04d}", cond, ch, v) for ch, v in values.items()]
    return rows


def has_muscles(cohort: Cohort) -> bool:
    """The cohort simulated sEMG (`CohortConfig.emg`)."""
    return any(p.muscles is not None and p.muscles.emg for p in cohort.participants)


def analyse_muscles(cohort: Cohort) -> MuscleAnalysis | None:
    """Reductions and repeated measures of every outcome; None without muscle data."""
    if not has_muscles(cohort):
        return None
    present = {c for p in cohort.participants if p.muscles for c in p.muscles.conditions}
    ctls = tuple(c for c in cohort.config.controllers if c in present)
    bases = tuple(sorted((b for b in registry.baselines() if b in present),
                         key=lambda b: b != PRIMARY_BASELINE))
    red: dict[tuple[str, str], list[Reduction]] = {}
    truth: dict[tuple[str, str], list[Reduction]] = {}
    rm: dict[str, list[RepeatedMeasures]] = {}
    for o in OUTCOMES:
        rows, trows = outcome_rows(cohort, o), outcome_rows(cohort, o, source="truth")
        for b in bases:
            red[(o, b)] = reductions(rows, b)
            truth[(o, b)] = reductions(trows, b)
        rm[o] = repeated_measures(rows, (*ctls, *bases))
    return MuscleAnalysis(ctls, bases, red, truth, rm)


def reductions_table(a: MuscleAnalysis) -> Table:
    """Every reduction with its interval, tests and the activation truth's reduction."""
    rows = []
    for (o, b), rs in a.reductions.items():
        true = {(t.channel, t.condition): t.mean_pct for t in a.truth[(o, b)]}
        for r in rs:
            rows.append((o, b, r.channel, r.condition, r.n, r.mean_pct, r.ci_low, r.ci_high,
                         r.p_value, r.p_holm, true.get((r.channel, r.condition), math.nan)))
    test = next((r.test for rs in a.reductions.values() for r in rs), "")
    return Table(("outcome", "baseline", "channel", "condition", "n", "reduction_pct",
                  "ci95_low", "ci95_high", "p", "p_holm", "truth_reduction_pct"),
                 tuple(rows), float_format=".3g",
                 title="Muscle activity: reduction against each baseline (simulated sEMG)",
                 notes=(f"Reduction per participant 100 (1 - condition / baseline), then the "
                        f"mean over participants. Test: {test} (per outcome and "
                        "baseline). truth_reduction_pct: the same from the activation "
                        "that generated the sEMG.", SIM_CAVEAT))


def repeated_table(a: MuscleAnalysis) -> Table:
    """The Friedman test per outcome and channel."""
    rows = [(o, r.channel, ", ".join(r.conditions), r.n, r.test, r.statistic, r.df,
             r.p_value) for o, rs in a.repeated.items() for r in rs]
    return Table(("outcome", "channel", "conditions", "n", "test", "statistic", "df", "p"),
                 tuple(rows), float_format=".3g",
                 title="Muscle activity: repeated measures across all conditions",
                 notes=("One test per outcome and channel, uncorrected; the paired "
                        "comparisons carry the Holm correction.",))


def _cycles(cohort: Cohort, cond: str, muscle: str) -> np.ndarray:
    """(participants, 101): each participant's mean cycle of both sides of `muscle`."""
    out = []
    for p in cohort.participants:
        c = p.muscles.conditions.get(cond) if p.muscles else None
        if c is None or not c.cycle:
            continue
        out.append(np.mean([c.cycle[f"{muscle}_{s}"] for s in ("left", "right")], axis=0))
    return np.array(out, dtype=np.float64)


def figures(cohort: Cohort, a: MuscleAnalysis) -> dict[str, tuple[bytes, bytes]]:
    """`muscle_envelope` and `muscle_reduction` as (PNG, SVG) bytes."""
    out: dict[str, tuple[bytes, bytes]] = {}
    fig = new_figure(8.0, 5.0)
    x = np.linspace(0.0, 100.0, 101)
    for i, muscle in enumerate(MUSCLES):
        ax = fig.add_subplot(2, 3, i + 1)
        for k, cond in enumerate(a.conditions):
            cyc = _cycles(cohort, cond, muscle)
            if cyc.size == 0:
                continue
            m = cyc.mean(axis=0)
            sd = cyc.std(axis=0, ddof=1) if cyc.shape[0] > 1 else np.zeros_like(m)
            col = controller_colour(cond, k)
            ax.plot(x, m, color=col, lw=1.1, label=controller_label(cond),
                    ls="--" if cond in a.baselines else "-")
            ax.fill_between(x, m - sd, m + sd, color=col, alpha=0.12, lw=0)
        ax.set_title(muscle.replace("_", " "), fontsize=8)
        ax.tick_params(labelsize=7)
        if i >= 3:
            ax.set_xlabel("lift cycle (%)", fontsize=7)
        if i % 3 == 0:
            ax.set_ylabel("envelope (fraction of MVC)", fontsize=7)
    fig.axes[0].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"Envelope over the lift cycle, both sides, mean +- 1 SD over "
                 f"{len(cohort.participants)} virtual participants (simulated)", fontsize=8.5)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.9, bottom=0.1, hspace=0.35, wspace=0.3)
    r = render_figure(fig)
    out["muscle_envelope"] = (r.png, r.svg)

    fig = new_figure(8.0, 3.2 * max(1, len(a.baselines)))
    for bi, b in enumerate(a.baselines):
        ax = fig.add_subplot(len(a.baselines), 1, bi + 1)
        rs = {(r.channel, r.condition): r for r in a.reductions[(PRIMARY_OUTCOME, b)]}
        shown = [c for c in a.conditions if c != b]
        width = 0.8 / max(1, len(shown))
        for k, cond in enumerate(shown):
            vals = [rs.get((ch, cond)) for ch in LABELS]
            mean = np.array([v.mean_pct if v else math.nan for v in vals])
            err = np.array([[v.mean_pct - v.ci_low if v else math.nan for v in vals],
                            [v.ci_high - v.mean_pct if v else math.nan for v in vals]])
            pos = np.arange(len(LABELS)) + (k - (len(shown) - 1) / 2) * width
            ax.bar(pos, mean, width, yerr=err, capsize=1.5, label=controller_label(cond),
                   color=controller_colour(cond, k), alpha=0.85, error_kw={"lw": 0.7})
        ax.axhline(0.0, color="0.4", lw=0.7)
        ax.set_xticks(range(len(LABELS)), [ch.replace("_", " ") for ch in LABELS],
                      rotation=35, ha="right", fontsize=6)
        ax.set_ylabel("reduction (%)", fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.set_title(f"{PRIMARY_OUTCOME} envelope against {controller_label(b)}, mean and "
                     "95 % t interval (simulated)", fontsize=8)
        ax.legend(fontsize=6, ncol=len(shown))
    fig.subplots_adjust(left=0.08, right=0.98, top=0.93, bottom=0.16, hspace=0.9)
    r = render_figure(fig)
    out["muscle_reduction"] = (r.png, r.svg)
    return out


def _cell(r: Reduction | None) -> str:
    if r is None or not math.isfinite(r.mean_pct):
        return "n/a"
    if not math.isfinite(r.ci_low):
        return f"{r.mean_pct:.1f}"
    p = "" if not math.isfinite(r.p_holm) else f", p_Holm {r.p_holm:.2g}"
    return f"{r.mean_pct:.1f} [{r.ci_low:.1f}, {r.ci_high:.1f}]{p}"


def markdown(a: MuscleAnalysis, n: int, heading: bool = True) -> str:
    """The README section: the primary outcome's reductions per channel and controller
    against each baseline, the truth check and the repeated-measures test."""
    lines = (["## Muscle activity (simulated sEMG)", ""] if heading else []) + [SIM_CAVEAT, ""]
    for b in a.baselines:
        rs = {(r.channel, r.condition): r for r in a.reductions[(PRIMARY_OUTCOME, b)]}
        tr = {(r.channel, r.condition): r for r in a.truth[(PRIMARY_OUTCOME, b)]}
        shown = [c for c in a.conditions if c != b]
        lines += [f"Reduction of the {PRIMARY_OUTCOME} normalised envelope against "
                  f"{controller_label(b)}, % (mean [95 % t interval], Holm-corrected p; "
                  f"{n} virtual participants; truth: the activation's reduction):", "",
                  "| channel | " + " | ".join(controller_label(c) for c in shown)
                  + " | truth (" + ", ".join(controller_label(c) for c in shown) + ") |",
                  "| --- |" + " --- |" * (len(shown) + 1)]
        for ch in LABELS:
            truth = ", ".join(f"{tr[(ch, c)].mean_pct:.1f}" if (ch, c) in tr else "n/a"
                              for c in shown)
            lines.append(f"| {ch} | " + " | ".join(_cell(rs.get((ch, c))) for c in shown)
                         + f" | {truth} |")
        lines.append("")
    test = next((r.test for rs in a.reductions.values() for r in rs), "")
    fr = a.repeated.get(PRIMARY_OUTCOME, [])
    ps = [r.p_value for r in fr if math.isfinite(r.p_value)]
    lines += [f"Paired test: {test}.",
              f"Repeated measures across {', '.join(a.conditions)}: "
              f"{fr[0].test if fr else 'Friedman'} per channel, p from "
              + (f"{min(ps):.2g} to {max(ps):.2g}" if ps else "n/a") + ".",
              "",
              "Files: `muscle_reductions.csv/.md` (peak, mean, iEMG against each baseline), "
              "`muscle_repeated.csv/.md`, `muscle_envelope.png/.svg`, "
              "`muscle_reduction.png/.svg`, `muscles.json`.", ""]
    return "\n".join(lines)


def write_outputs(cohort: Cohort, put: Callable[[str, str | bytes], None]) -> str:
    """Write the muscle tables, figures and JSON with `put(name, data)`; returns the
    README section ("" when the cohort has no muscle data)."""
    a = analyse_muscles(cohort)
    if a is None:
        return ""
    for stem, table in (("muscle_reductions", reductions_table(a)),
                        ("muscle_repeated", repeated_table(a))):
        put(f"{stem}.csv", table.to_csv())
        put(f"{stem}.md", table.to_markdown())
    for stem, (png, svg) in figures(cohort, a).items():
        put(f"{stem}.png", png)
        put(f"{stem}.svg", svg)
    put("muscles.json", json.dumps({"outcomes": list(OUTCOMES), "units": OUTCOME_UNITS,
                                    **a.to_dict()}, indent=1, allow_nan=False))
    return "\n" + markdown(a, len(cohort.participants))


def replication_section(figures_out: dict[str, tuple[bytes, bytes]], participants: int,
                        seed: int, models: Any = None, utilities: Any = None,
                        log: Callable[[str], None] = print,
                        controllers: Sequence[str] | None = None) -> str:
    """For the replication report: an EMG cohort of `participants` (seed `seed`, the
    given model and utility sets or the defaults), its figures added to
    `figures_out`; returns the section as Markdown (tables as `Table.to_markdown`)."""
    from controller.evaluation.cohort import CohortConfig, simulate_cohort

    cfg = CohortConfig(participants=max(2, participants), seed=seed, emg=True)
    if controllers:
        cfg = replace(cfg, controllers=tuple(controllers))
    log(f"muscle activity: simulating an EMG cohort of {cfg.participants}")
    cohort = simulate_cohort(cfg, models, utilities)
    a = analyse_muscles(cohort)
    if a is None:
        return ""
    figures_out.update(figures(cohort, a))
    return markdown(a, len(cohort.participants), heading=False)
