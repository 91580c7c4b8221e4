"""The paper's method figures, redrawn from the project's own models: utility
differences per action, actuator torque against deflection at several precompressions,
the chi-square tail that turns a DTW distance into a likelihood, and the motion models
with their 95 % regions. Also the two figures of the replication report that the paper
does not have: decision gain against donning offset, and simulated stair kinematics
against published ranges.

Each returns a `Figure` on an Agg canvas (`rendering.render_figure` gives PNG and SVG).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from scipy.stats import chi2

from controller.evaluation.rendering import DEFAULT_DPI, KIND_COLOURS, KIND_LABELS, new_figure
from controller.evaluation.timeline import ModelSetLike, draw_models
from controller.lowlevel.actuator import (
    PAPER_ACTUATOR,
    MaccepaParams,
    maccepa_torque,
    max_deflection,
)
from controller.tick_record import ACTION_NAMES, MODEL_NAMES

#: Precompressions drawn in the actuator figure (percent of 22 mm), as in the paper's.
PRECOMPRESSIONS: tuple[float, ...] = (0.0, 25.0, 50.0, 75.0, 100.0)
_ACTION_COLOURS = ("0.4", "#1f78b4", "#e31a1c", "#33a02c")


def utility_difference_figure(values: np.ndarray, dpi: int = DEFAULT_DPI) -> Figure:
    """U(a, motion, s) - U(no lock, motion, s) for each action and the three lifting
    motions (paper, figure "q functions"); `values` is the `(4, 4, N)` utility table
    (actions, categories in `CATEGORY_NAMES` order, progress)."""
    v = np.asarray(values, dtype=np.float64)
    n = v.shape[2]
    s = np.linspace(0.0, 1.0, n)
    fig = new_figure(6.0, 7.0, dpi)
    axes = fig.subplots(3, 1, sharex=True)
    for j, (ax, name) in enumerate(zip(axes, MODEL_NAMES, strict=True)):
        for a in range(v.shape[0]):
            ax.plot(s, v[a, j] - v[0, j], color=_ACTION_COLOURS[a], lw=1.3,
                    label=ACTION_NAMES[a].replace("_", " "))
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_title(KIND_LABELS.get(name, name), fontsize=9)
        ax.set_ylabel("U(a) - U(no lock) (Nm$^2$)", fontsize=8)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].legend(fontsize=7, ncol=4, loc="lower left")
    axes[-1].set_xlabel("progress s")
    fig.subplots_adjust(left=0.16, right=0.97, top=0.95, bottom=0.08, hspace=0.3)
    return fig


def actuator_figure(params: MaccepaParams = PAPER_ACTUATOR,
                    precompressions: Sequence[float] = PRECOMPRESSIONS,
                    dpi: int = DEFAULT_DPI) -> Figure:
    """Torque of one hip module against deflection for several precompressions, each
    up to its compression limit (paper, figure "torque-deflection")."""
    fig = new_figure(6.0, 4.0, dpi)
    ax = fig.add_subplot(1, 1, 1)
    for i, pc in enumerate(precompressions):
        top = max_deflection(pc, params)
        alpha = np.linspace(0.0, top, 200)
        tau = np.asarray(maccepa_torque(alpha, pc, params), dtype=np.float64)
        ax.plot(np.degrees(alpha), tau, lw=1.4, color=f"C{i}", label=f"P = {pc:g} %")
    ax.set_xlabel("deflection alpha (deg)")
    ax.set_ylabel("torque (Nm)")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=8)
    fig.subplots_adjust(left=0.12, right=0.97, top=0.95, bottom=0.13)
    return fig


def chi_square_figure(distance: float = 7.5, length: int = 3,
                      dpi: int = DEFAULT_DPI) -> Figure:
    """The chi-square density with `2 length` degrees of freedom and the tail above
    `distance` shaded: P(obs | model) (paper, figure "chi squared")."""
    df = 2 * length
    x = np.linspace(0.0, max(25.0, 3.0 * distance), 500)
    y = chi2.pdf(x, df)
    fig = new_figure(6.0, 3.6, dpi)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(x, y, color="black", lw=1.2)
    tail = x >= distance
    ax.fill_between(x[tail], 0.0, y[tail], color="#1f78b4", alpha=0.4,
                    label=f"P(obs|model) = {chi2.sf(distance, df):.4f}")
    ax.axvline(distance, color="#1f78b4", ls="--", lw=0.8)
    ax.set_xlabel(f"DTW distance D (chi-square, {df} degrees of freedom)")
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    ax.grid(True, lw=0.3, alpha=0.5)
    fig.subplots_adjust(left=0.12, right=0.97, top=0.95, bottom=0.15)
    return fig


def motion_models_figure(models: ModelSetLike, dpi: int = DEFAULT_DPI) -> Figure:
    """The motion models, means over the online part and 95 % regions, left against
    right hip flexion (paper, figure "motion models"), with the diagonal."""
    fig = new_figure(5.2, 5.2, dpi)
    ax = fig.add_subplot(1, 1, 1)
    handles, extent = draw_models(ax, models)
    lo, hi = (min(extent) - 5.0, max(extent) + 5.0) if extent else (0.0, 1.0)
    ax.plot([lo, hi], [lo, hi], ls="--", lw=0.7, color="0.5")
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("left hip flexion (deg)")
    ax.set_ylabel("right hip flexion (deg)")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(handles=handles, loc="upper left", fontsize=8)
    fig.subplots_adjust(left=0.14, right=0.97, top=0.97, bottom=0.1)
    return fig


def offset_figure(offsets_deg: np.ndarray, gains: np.ndarray, slope: float,
                  intercept: float, xlabel: str, dpi: int = DEFAULT_DPI) -> Figure:
    """Per participant, UMC minus E-UMC correct decisions against a donning offset
    measure, with the least-squares line."""
    x = np.asarray(offsets_deg, dtype=np.float64)
    y = np.asarray(gains, dtype=np.float64)
    fig = new_figure(5.5, 4.0, dpi)
    ax = fig.add_subplot(1, 1, 1)
    ax.scatter(x, y, s=14, color="#1f78b4", edgecolors="black", linewidths=0.3)
    if x.size:
        xs = np.linspace(float(x.min()), float(x.max()), 2)
        ax.plot(xs, intercept + slope * xs, color="#e31a1c", lw=1.2,
                label=f"slope {slope:.2f} per deg")
        ax.legend(fontsize=8)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("UMC - E-UMC correct decisions (per 20 lifts)")
    ax.grid(True, lw=0.3, alpha=0.5)
    fig.subplots_adjust(left=0.14, right=0.97, top=0.95, bottom=0.13)
    return fig


def stairs_figure(cycles: Mapping[str, np.ndarray],
                  published: Mapping[str, tuple[float, float]],
                  dpi: int = DEFAULT_DPI) -> Figure:
    """Simulated hip flexion over one stair cycle (rows: participants' mean cycles,
    degrees) for ascent and descent, with the published range of motion as a band
    above the curves' minimum."""
    fig = new_figure(9.0, 3.6, dpi)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, kind in zip(axes, ("stairs_up", "stairs_down"), strict=True):
        c = np.asarray(cycles.get(kind, np.zeros((0, 2))), dtype=np.float64)
        if c.size:
            ph = np.linspace(0.0, 100.0, c.shape[1])
            for row in c:
                ax.plot(ph, row, color="0.6", lw=0.5, alpha=0.6)
            mean = c.mean(axis=0)
            ax.plot(ph, mean, color=KIND_COLOURS.get("stoop_left", "C0"), lw=1.6,
                    label="simulated, mean")
            lo, hi = published.get(kind, (np.nan, np.nan))
            base = float(mean.min())
            ax.axhspan(base + lo, base + hi, color="#ff7f00", alpha=0.2,
                       label="published range of motion above the minimum")
        ax.set_title("ascent" if kind == "stairs_up" else "descent", fontsize=9)
        ax.set_xlabel("gait cycle (%)")
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].set_ylabel("hip flexion (deg)")
    axes[0].legend(fontsize=7, loc="upper right")
    fig.subplots_adjust(left=0.08, right=0.98, top=0.9, bottom=0.15, wspace=0.06)
    return fig
