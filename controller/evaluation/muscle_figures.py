"""The muscle-activity figures of a study: the envelope over the normalised lift cycle per
controller (mean over participants and a band of one standard deviation), and the
reduction of each muscle's activity per controller against a baseline (mean and 95 %
interval). Pure: the numbers come in, a matplotlib figure goes out
(`controller.evaluation.rendering.render_figure` draws it)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from controller.controllers import registry
from controller.evaluation.rendering import DEFAULT_DPI, controller_colour, new_figure

#: Panels per row of the envelope figure.
_COLUMNS = 4


def envelope_cycle_figure(cycles: Mapping[str, Mapping[str, Any]], channels: Sequence[str],
                          unit: str, title: str = "", dpi: int = DEFAULT_DPI) -> Figure:
    """One panel per channel: per condition the mean envelope over 0-100 % of the lift
    (`cycles[condition]["mean"]`, points x channels) with a band of +- one SD across
    participants (`["sd"]`); `n` participants in the legend."""
    n = max(1, len(channels))
    rows = math.ceil(n / _COLUMNS)
    fig = new_figure(2.6 * min(n, _COLUMNS), 2.0 * rows + 0.6, dpi=dpi)
    axes = np.atleast_1d(fig.subplots(rows, min(n, _COLUMNS), squeeze=False)).ravel()
    for c, ch in enumerate(channels):
        ax = axes[c]
        for k, (cond, cy) in enumerate(cycles.items()):
            mean = np.asarray(cy["mean"])[:, c]
            sd = np.asarray(cy["sd"])[:, c]
            x = np.linspace(0.0, 100.0, mean.size)
            colour = controller_colour(cond, k)
            ax.fill_between(x, mean - sd, mean + sd, color=colour, alpha=0.15, lw=0)
            ax.plot(x, mean, color=colour, lw=1.2,
                    label=f"{registry.label(cond)} (n={cy['n']})")
        ax.set_title(ch.replace("_", " "), fontsize=8)
        ax.set_xlim(0, 100)
        if c % _COLUMNS == 0:
            ax.set_ylabel(unit, fontsize=7)
        if c >= n - _COLUMNS:
            ax.set_xlabel("lift cycle (%)", fontsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    if channels and cycles:
        axes[0].legend(fontsize=6, loc="upper right")
    fig.suptitle(title or "EMG envelope over the normalised lift cycle (mean, band +- 1 SD "
                 "across participants)", fontsize=9)
    fig.tight_layout()
    return fig


def reduction_figure(reductions: Sequence[Mapping[str, Any]], channels: Sequence[str],
                     baseline: str, metric: str = "mean", dpi: int = DEFAULT_DPI) -> Figure:
    """Per channel, each condition's mean reduction against `baseline` (%) with its 95 %
    interval; rows of `muscle_stats.Reduction.to_dict()` for one group and metric."""
    mine = [r for r in reductions if r.get("baseline") == baseline]
    conds = list(dict.fromkeys(str(r["condition"]) for r in mine))
    fig = new_figure(max(5.0, 0.55 * len(channels) * max(1, len(conds)) + 1.5), 3.4, dpi=dpi)
    ax = fig.subplots()
    width = 0.8 / max(1, len(conds))
    for k, cond in enumerate(conds):
        xs, ys, lo, hi = [], [], [], []
        for c, ch in enumerate(channels):
            r = next((r for r in mine if r["condition"] == cond and r["channel"] == ch), None)
            if r is None or r.get("mean_pct") is None:
                continue
            xs.append(c + (k - (len(conds) - 1) / 2) * width)
            ys.append(float(r["mean_pct"]))
            lo.append(float(r["mean_pct"]) - float(r["ci_low"])
                      if r.get("ci_low") is not None else 0.0)
            hi.append(float(r["ci_high"]) - float(r["mean_pct"])
                      if r.get("ci_high") is not None else 0.0)
        ax.bar(xs, ys, width=width * 0.9, color=controller_colour(cond, k),
               label=registry.label(cond), yerr=[lo, hi], capsize=2,
               error_kw={"lw": 0.8})
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xticks(range(len(channels)))
    ax.set_xticklabels([ch.replace("_", " ") for ch in channels], rotation=45, ha="right",
                       fontsize=7)
    ax.set_ylabel(f"reduction of the {metric} envelope (%)")
    ax.set_title(f"Muscle activity against {registry.label(baseline)} (mean, 95 % CI)",
                 fontsize=9)
    if conds:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
