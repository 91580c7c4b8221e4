"""Study figures: the paper's peak torque scatter and the onset-to-lock histogram.

Both take a study's `RecordingEvaluation`s and return a `Figure` on an Agg canvas;
`controller.evaluation.rendering.render_figure` turns it into PNG and SVG bytes. The
five-panel controller output figure is in `controller.evaluation.timeline`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.markers import MarkerStyle

from controller.evaluation.lifts import LIFT_KINDS
from controller.evaluation.metrics import LockTiming, onset_to_lock_times
from controller.evaluation.rendering import (
    DEFAULT_DPI,
    KIND_COLOURS,
    KIND_LABELS,
    controller_colour,
    controller_marker,
    new_figure,
)
from controller.evaluation.study import RecordingEvaluation, controller_label

#: Size of one panel of the peak torque scatter (inches).
SCATTER_PANEL_IN: tuple[float, float] = (4.0, 4.2)
#: Size of the onset-to-lock histogram (inches).
HISTOGRAM_IN: tuple[float, float] = (9.0, 3.6)


def _controllers(
    evaluations: Sequence[RecordingEvaluation], given: Sequence[str] | None
) -> list[str]:
    if given is not None:
        return list(given)
    return list(dict.fromkeys(e.controller for e in evaluations if e.lifts))


def _peaks(
    evaluations: Sequence[RecordingEvaluation], controller: str, kind: str
) -> tuple[np.ndarray, np.ndarray]:
    """(right, left) peak torques of the controller's lifts of `kind`, finite only."""
    pts = [
        (o.peak_torque_right, o.peak_torque_left)
        for e in evaluations
        if e.controller == controller
        for o in e.lifts
        if o.lift.kind == kind
    ]
    a = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    a = a[np.isfinite(a).all(axis=1)]
    return a[:, 0], a[:, 1]


def peak_torque_figure(
    evaluations: Sequence[RecordingEvaluation],
    controllers: Sequence[str] | None = None,
    layout: Literal["panels", "single"] = "panels",
    dpi: int = DEFAULT_DPI,
) -> Figure:
    """The paper's peak torque scatter: per lift, the peak right (horizontal) and left
    (vertical) exoskeleton torque, coloured by motion (squat blue, stoop left green,
    stoop right red), with a marker per controller.

    Args:
        evaluations: the study's recordings; lifts without torque are left out.
        controllers: which controllers and their order (default: all, as they appear).
        layout: "panels", one panel per controller side by side on shared axes as in
            the paper (each `SCATTER_PANEL_IN`); or "single", every controller in one
            panel, told apart by marker.
        dpi: pixels per inch.

    The dashed diagonal marks symmetric support: squats should lie on it, stoops near
    their supporting side's axis.
    """
    if layout not in ("panels", "single"):
        raise ValueError(f"layout must be 'panels' or 'single', got {layout!r}")
    ctls = _controllers(evaluations, controllers)
    n_panels = max(1, len(ctls)) if layout == "panels" else 1
    w, h = SCATTER_PANEL_IN
    fig = new_figure(w * n_panels, h, dpi)
    axes_arr = fig.subplots(1, n_panels, sharex=True, sharey=True, squeeze=False)[0]
    axes: list[Axes] = list(axes_arr)
    top = 0.0
    for i, c in enumerate(ctls):
        ax = axes[i] if layout == "panels" else axes[0]
        marker = controller_marker(c, i)
        # A black outline for filled markers; a line marker ("x", "+") is all outline,
        # drawn in the motion's colour (matplotlib would ignore the black, and warn).
        outline = "black" if MarkerStyle(marker).is_filled() else None
        for k in LIFT_KINDS:
            x, y = _peaks(evaluations, c, k)
            if x.size:
                top = max(top, float(x.max()), float(y.max()))
            ax.scatter(
                x, y, s=22, marker=marker, c=KIND_COLOURS[k], edgecolors=outline,
                linewidths=0.4, alpha=0.85,
            )
        if layout == "panels":
            ax.set_title(controller_label(c))
    lim = 1.0 if top <= 0 else top * 1.08
    for j, ax in enumerate(axes):
        ax.plot([0, lim], [0, lim], ls="--", lw=0.8, color="0.5", zorder=0)
        ax.set_xlim(0, lim)
        ax.set_ylim(0, lim)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.set_xlabel("peak right torque (Nm)")
        if j == 0:
            ax.set_ylabel("peak left torque (Nm)")
    handles: list[Line2D] = [
        Line2D([], [], ls="", marker="o", color=KIND_COLOURS[k], markeredgecolor="black",
               label=KIND_LABELS[k])
        for k in LIFT_KINDS
    ]
    if layout == "single" or not ctls:
        handles += [
            Line2D([], [], ls="", marker=controller_marker(c, i), color="white",
                   markeredgecolor="black", label=controller_label(c))
            for i, c in enumerate(ctls)
        ]
    axes[0].legend(handles=handles, loc="upper left", fontsize=7, framealpha=0.9)
    if not ctls:
        axes[0].text(0.5, 0.5, "no lifts", ha="center", va="center", transform=axes[0].transAxes)
    fig.subplots_adjust(left=0.08 if n_panels > 1 else 0.14, right=0.98, bottom=0.13, top=0.92,
                        wspace=0.08)
    return fig


def onset_to_lock_figure(
    evaluations: Sequence[RecordingEvaluation],
    controllers: Sequence[str] | None = None,
    bin_s: float = 0.05,
    dpi: int = DEFAULT_DPI,
) -> Figure:
    """Histograms of the time from lift onset to the first lock on either side (left
    panel) and to the correct side(s) held (right panel), one outline per controller,
    its median dashed. Lifts that never locked are counted in the legend, not drawn.

    Args:
        evaluations: the study's recordings.
        controllers: which controllers and their order (default: all, as they appear).
        bin_s: bin width in seconds; bins start at 0 and are shared by all outlines.
        dpi: pixels per inch. The size is `HISTOGRAM_IN`.
    """
    if not bin_s > 0:
        raise ValueError(f"bin_s must be positive, got {bin_s}")
    ctls = _controllers(evaluations, controllers)
    fig = new_figure(*HISTOGRAM_IN, dpi=dpi)
    axes: list[Axes] = list(fig.subplots(1, 2, sharey=True))
    times: dict[tuple[str, str], np.ndarray] = {}
    top = 0.0
    whichs: tuple[LockTiming, LockTiming] = ("first", "correct")
    for c in ctls:
        outs = [o for e in evaluations if e.controller == c for o in e.lifts]
        for which in whichs:
            x = onset_to_lock_times(outs, which)
            times[(c, which)] = x
            ok = x[np.isfinite(x)]
            if ok.size:
                top = max(top, float(ok.max()))
    n_bins = max(1, math.ceil((top + 1e-9) / bin_s))
    edges = np.arange(n_bins + 1) * bin_s
    titles = {"first": "onset to first lock (either side)",
              "correct": "onset to correct side(s) locked"}
    peak_count = 1
    for x in times.values():
        ok = x[np.isfinite(x)]
        if ok.size:
            peak_count = max(peak_count, int(np.histogram(ok, bins=edges)[0].max()))
    for ax, which in zip(axes, whichs, strict=True):
        drawn = False
        for i, c in enumerate(ctls):
            x = times[(c, which)]
            ok = x[np.isfinite(x)]
            colour = controller_colour(c, i)
            label = f"{controller_label(c)}: {ok.size}/{x.size} locked"
            if ok.size:
                med = float(np.median(ok))
                ax.hist(ok, bins=edges.tolist(), histtype="step", lw=1.4, color=colour,
                        label=f"{label}, median {med:.2f} s")
                ax.axvline(med, color=colour, ls="--", lw=0.9)
                drawn = True
            else:
                ax.plot([], [], color=colour, label=label)
        if not drawn:
            ax.text(0.5, 0.5, "no lift locked", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(titles[which])
        ax.set_xlabel("time from lift onset (s)")
        ax.set_xlim(0, float(edges[-1]))
        ax.grid(True, lw=0.3, alpha=0.5)
        if ctls:
            ax.legend(fontsize=7, loc="upper right")
    axes[0].set_ylabel("lifts")
    axes[0].set_ylim(0, peak_count * 1.35)  # headroom for the legend
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.15, top=0.9, wspace=0.08)
    return fig
