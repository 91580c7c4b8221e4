"""The paper's five-panel controller output figure for a stretch of ticks.

(A) the motion models in the plane of left versus right hip flexion, means and 95 %
confidence ellipses at a few progress points, with the wearer's hip trajectory on top;
(B) the hip angles over time; (C) the four posteriors; (D) the progress estimate
`s_curr` of the most probable model (none while "other" is the most probable
category); (E) the control signals: the decided action and the held lock command per
side.

As in the paper, when the lifts of the stretch are given the hip-flexion part of each
lift (onset to peak flexion, the peak being the largest mean of both hips within the
lift) is drawn opaque in (B) and in black on the models in (A); the rest is faint.
Every panel also shades each lift in its motion's colour.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Ellipse, Patch
from scipy.stats import chi2

from controller.evaluation.columns import Columns, FloatArray, TickData
from controller.evaluation.decimation import column_extremes, step_changes, true_runs
from controller.evaluation.lifts import LIFT_KINDS, Lift
from controller.evaluation.rendering import DEFAULT_DPI, KIND_COLOURS, KIND_LABELS, new_figure
from controller.tick_record import ACTION_NAMES, CATEGORY_NAMES

#: Size of the figure (inches): the paper's full text width.
TIMELINE_IN: tuple[float, float] = (13.0, 8.0)
#: Progress points at which the confidence ellipses are drawn (the online half).
DEFAULT_PROGRESS_POINTS: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)
#: Squared Mahalanobis radius of the 95 % region of a 2-D Gaussian (5.99).
CHI2_95_2D = float(chi2.ppf(0.95, df=2))
#: Samples further apart than this are not joined by a line (a 10 Hz UMC runs every
#: 0.1 s; the idle E-UMC computes no posterior at all).
MAX_GAP_S = 0.15
_LEFT, _RIGHT = "#6a3d9a", "#b15928"
#: Event markers (console, LSL, system): a colour no panel uses for data.
_MARKER = "#e7298a"
#: Columns per pixel of a time panel's width into which its lines are thinned (at most
#: four samples a column, `decimation.column_extremes`): two, so that the columns need
#: not line up with the pixels and the SVG can be zoomed a little.
COLUMNS_PER_PIXEL = 2


class MotionModelLike(Protocol):
    """What the figure reads of a motion model (`controller.intent.motion_model.MotionModel`)."""

    @property
    def name(self) -> str:
        """squat, stoop_left or stoop_right."""
        ...

    @property
    def mean(self) -> FloatArray:
        """(N, 2) mean hip flexion (rad), left then right, over progress 0..1."""
        ...

    @property
    def cov(self) -> FloatArray:
        """(N, 2, 2) covariance per progress sample (rad^2)."""
        ...


class ModelSetLike(Protocol):
    """What the figure reads of a model set (`controller.intent.motion_model.ModelSet`)."""

    def ordered(self) -> Sequence[MotionModelLike]:
        """The models in `MODEL_NAMES` order."""
        ...


def confidence_ellipse(
    mean: FloatArray, cov: FloatArray, level_chi2: float = CHI2_95_2D
) -> tuple[float, float, float]:
    """Width, height and angle (degrees) of the ellipse `x^T cov^-1 x = level_chi2`
    around `mean`, for `matplotlib.patches.Ellipse` (full axis lengths)."""
    c = np.asarray(cov, dtype=np.float64)
    if c.shape != (2, 2):
        raise ValueError(f"covariance must be 2x2, got {c.shape}")
    vals, vecs = np.linalg.eigh(c)
    if vals[0] <= 0:
        raise ValueError("covariance must be positive definite")
    big = vecs[:, 1]
    angle = float(np.degrees(np.arctan2(big[1], big[0])))
    return 2 * float(np.sqrt(level_chi2 * vals[1])), 2 * float(np.sqrt(level_chi2 * vals[0])), angle


def _gap_broken(t: FloatArray, y: FloatArray, max_gap: float) -> tuple[FloatArray, FloatArray]:
    """The finite samples of `y`, with a NaN inserted wherever two are further apart in
    time than `max_gap`, so a line plot does not bridge ticks where nothing was computed.
    The break sits at the time of the sample before it, so time stays in order."""
    ok = np.isfinite(y)
    tt, yy = t[ok], y[ok]
    if tt.size < 2:
        return tt, yy
    breaks = np.flatnonzero(np.diff(tt) > max_gap) + 1
    return (
        np.insert(tt, breaks, tt[breaks - 1]).astype(np.float64),
        np.insert(yy, breaks, np.nan).astype(np.float64),
    )


def _time_ordered(t: FloatArray) -> bool:
    """Whether `t` is a clean time axis (finite, never going back): only then are lines
    thinned and strips drawn as spans; otherwise every sample is drawn as it comes."""
    return bool(np.isfinite(t).all() and (t.size < 2 or np.all(np.diff(t) >= 0)))


def _columns(fig: Figure, ax: Axes) -> int:
    """Thinning columns across `ax` (`COLUMNS_PER_PIXEL` per pixel of its width)."""
    width_px = ax.get_position().width * fig.get_figwidth() * fig.dpi
    return max(1, math.ceil(width_px * COLUMNS_PER_PIXEL))


def _thin(x: FloatArray, y: FloatArray, columns: int, span: tuple[float, float],
          ordered: bool) -> tuple[FloatArray, FloatArray]:
    """The samples of the line `(x, y)` that draw it as a whole into `columns` columns
    across `span` (every column's first, last, lowest and highest sample, every break);
    the line itself when it is short or its time is not in order."""
    if not ordered or x.size <= 4 * columns:
        return x, y
    keep = column_extremes(x, y, columns, *span)
    return x[keep], y[keep]


def _flexion_end(q_mean: FloatArray, lift: Lift, offset: int) -> int:
    """Index (into the stretch) of the lift's peak flexion."""
    lo, hi = max(lift.start - offset, 0), min(lift.end - offset, q_mean.size - 1)
    seg = q_mean[lo : hi + 1]
    if seg.size == 0 or not np.isfinite(seg).any():
        return lo
    return lo + int(np.nanargmax(seg))


def _shade_lifts(ax: Axes, lifts: Sequence[Lift], t: FloatArray, offset: int) -> None:
    """Each lift shaded over the panel's height in its motion's colour: the rectangles
    `axvspan` would draw, as one collection (one artist, not one per lift)."""
    n = t.size
    verts: list[list[tuple[float, float]]] = []
    colours: list[str] = []
    for lf in lifts:
        a, b = max(lf.start - offset, 0), min(lf.end - offset, n - 1)
        if a <= b:
            x0, x1 = float(t[a]), float(t[b])
            verts.append([(x0, 0.0), (x1, 0.0), (x1, 1.0), (x0, 1.0)])
            colours.append(KIND_COLOURS[lf.kind])
    if verts:
        ax.add_collection(PolyCollection(
            verts, facecolors=colours, edgecolors="none", linewidths=0, alpha=0.08,
            transform=ax.get_xaxis_transform(which="grid")), autolim=False)


def _held(ax: Axes, t: FloatArray, held: npt.NDArray[np.bool_], band: tuple[float, float],
          colour: str, label: str, ordered: bool) -> None:
    """A lock command's strip in panel E: filled where `held`, each run of held ticks
    from its first tick's time to its last's (as `fill_between(..., step="post")`
    fills it), drawn as one rectangle per run rather than a polygon through every tick."""
    if not ordered:
        ax.fill_between(t, *band, where=held, step="post", color=colour, alpha=0.6, lw=0,
                        label=label)
        return
    spans = [(float(t[a]), float(t[b] - t[a])) for a, b in true_runs(held) if b > a]
    ax.broken_barh(spans, (band[0], band[1] - band[0]), color=colour, alpha=0.6, lw=0,
                   label=label)


def _panel_label(ax: Axes, text: str) -> None:
    ax.set_title(text, loc="left", fontweight="bold", fontsize=9, pad=3)


def _legend(ax: Axes, ncol: int) -> None:
    # In the title row, right-aligned: inside the axes a legend would hide data.
    ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=ncol, fontsize=7,
              frameon=False, borderaxespad=0.2, handlelength=1.5)


def _missing(ax: Axes, what: str) -> None:
    ax.text(0.5, 0.5, f"{what} not recorded by this controller", ha="center", va="center",
            transform=ax.transAxes, color="0.4")


def draw_models(ax: Axes, models: ModelSetLike,
                progress_points: Sequence[float] = DEFAULT_PROGRESS_POINTS
                ) -> tuple[list[Line2D | Patch], list[float]]:
    """Each model's mean over its online part (degrees, left vs right hip) and its 95 %
    confidence ellipses at `progress_points`, on `ax`; returns the legend handles and
    the values drawn (for the axis range). Panel A of the controller output figure and
    the motion-model figure of the replication report."""
    handles: list[Line2D | Patch] = []
    extent: list[float] = []
    for m in models.ordered():
        colour = KIND_COLOURS.get(m.name, "0.3")
        mean = np.degrees(np.asarray(m.mean, dtype=np.float64))
        cov = np.asarray(m.cov, dtype=np.float64) * (180.0 / np.pi) ** 2
        online = getattr(m, "online_n", None)  # MotionModel marks its online half
        last = int(online) if isinstance(online, int) else mean.shape[0]
        ax.plot(mean[:last, 0], mean[:last, 1], color=colour, lw=1.6)
        extent += mean[:last].ravel().tolist()
        for s in progress_points:
            k = round(s * (mean.shape[0] - 1))
            w, h, ang = confidence_ellipse(mean[k], cov[k])
            ax.add_patch(Ellipse((float(mean[k, 0]), float(mean[k, 1])), w, h, angle=ang,
                                 fill=False, ec=colour, lw=0.8, alpha=0.9))
            extent += [float(mean[k].min()) - w / 2, float(mean[k].max()) + w / 2]
        handles.append(Line2D([], [], color=colour, label=KIND_LABELS.get(m.name, m.name)))
    return handles, extent


def controller_output_figure(
    columns: Columns,
    start: int = 0,
    stop: int | None = None,
    models: ModelSetLike | None = None,
    lifts: Sequence[Lift] = (),
    progress_points: Sequence[float] = DEFAULT_PROGRESS_POINTS,
    title: str = "",
    dpi: int = DEFAULT_DPI,
    markers: Sequence[tuple[float, str]] = (),
) -> Figure:
    """The five-panel controller output of ticks `start..stop-1` (size `TIMELINE_IN`).

    Args:
        columns: the recording; needs `q_left`, `q_right`, `action`, `lock_left`,
            `lock_right`; uses `t`, `post_*` and `s_curr_*` when present (a PEC
            recording has no posteriors: panels C and D say so).
        start, stop: the stretch, tick indices into `columns` (stop exclusive; None is
            the end).
        models: the model set for panel A; without it A shows the trajectory only.
        lifts: lifts of the recording (indices into `columns`); those overlapping the
            stretch are shaded and their hip-flexion parts highlighted.
        progress_points: progress values (0..1) at which ellipses are drawn.
        title: an optional figure title.
        dpi: pixels per inch.
        markers: event markers as (device time `t`, label); those inside the stretch
            are drawn as dashed lines across panels B-E, labelled on B.

    Time runs from the stretch's first tick. Angles are shown in degrees.
    """
    full = TickData.of(columns)
    stop = len(full) if stop is None else stop
    cols = full.select(start, stop)
    n = len(cols)
    if n == 0:
        raise ValueError("the stretch has no ticks")
    for s in progress_points:
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"progress points must lie in 0..1, got {s}")
    t_abs = cols.time()
    t = t_abs - t_abs[0]
    ql, qr = np.degrees(cols.float_("q_left")), np.degrees(cols.float_("q_right"))
    inside = [lf for lf in lifts if lf.end >= start and lf.start < stop]
    qm = (ql + qr) / 2.0
    flex = np.zeros(n, dtype=bool)
    parts: list[tuple[int, int]] = []
    for lf in inside:
        a = max(lf.start - start, 0)
        b = _flexion_end(qm, lf, start)
        if a <= b:
            flex[a : b + 1] = True
            parts.append((a, b))

    fig = new_figure(*TIMELINE_IN, dpi=dpi)
    grid = fig.add_gridspec(4, 2, width_ratios=(1.0, 2.0), left=0.055, right=0.985,
                            bottom=0.07, top=0.92 if title else 0.95, wspace=0.16, hspace=0.3)
    ax_a = fig.add_subplot(grid[:, 0])
    ax_b = fig.add_subplot(grid[0, 1])
    ax_c = fig.add_subplot(grid[1, 1], sharex=ax_b)
    ax_d = fig.add_subplot(grid[2, 1], sharex=ax_b)
    ax_e = fig.add_subplot(grid[3, 1], sharex=ax_b)
    if title:
        fig.suptitle(title)

    ordered = _time_ordered(t)
    span = (float(t[0]), float(t[-1]))
    n_columns = _columns(fig, ax_b)

    # (A) models and trajectory
    handles: list[Line2D | Patch] = []
    angles = np.concatenate([ql, qr])
    angles = angles[np.isfinite(angles)]
    # Only the range of the values is used (below): their lowest and highest are enough.
    extent: list[float] = [float(angles.min()), float(angles.max())] if angles.size else []
    if models is not None:
        h_models, e_models = draw_models(ax_a, models, progress_points)
        handles += h_models
        extent += e_models
    if parts:
        ax_a.plot(ql, qr, color="0.6", lw=0.5, alpha=0.4)
        for a, b in parts:
            ax_a.plot(ql[a : b + 1], qr[a : b + 1], color="black", lw=0.9)
        handles.append(Line2D([], [], color="black", label="hip flexion part of lifts"))
    else:
        ax_a.plot(ql, qr, color="black", lw=0.6)
        handles.append(Line2D([], [], color="black", label="hip trajectory"))
    ax_a.set_xlabel("left hip flexion (deg)")
    ax_a.set_ylabel("right hip flexion (deg)")
    # One range for both axes so that the diagonal (symmetric flexion) is at 45 degrees.
    lo, hi = (min(extent) - 5.0, max(extent) + 5.0) if extent else (0.0, 1.0)
    ax_a.set_xlim(lo, hi)
    ax_a.set_ylim(lo, hi)
    ax_a.set_aspect("equal", adjustable="box")
    ax_a.grid(True, lw=0.3, alpha=0.5)
    ax_a.legend(handles=handles, loc="upper left", fontsize=7)
    _panel_label(ax_a, "(A) motion models")

    # (B) angles
    for q, colour, label in ((ql, _LEFT, "left"), (qr, _RIGHT, "right")):
        if parts:
            ax_b.plot(*_thin(t, q, n_columns, span, ordered), color=colour, lw=0.9, alpha=0.3)
            ax_b.plot(*_thin(t, np.where(flex, q, np.nan), n_columns, span, ordered),
                      color=colour, lw=1.1, label=label)
        else:
            ax_b.plot(*_thin(t, q, n_columns, span, ordered), color=colour, lw=1.0, label=label)
    ax_b.set_ylabel("hip flexion (deg)")
    _legend(ax_b, 2)
    _panel_label(ax_b, "(B) hip angles")

    # (C) posteriors
    post_names = [f"post_{c}" for c in CATEGORY_NAMES]
    has_post = all(p in cols for p in post_names) and any(
        np.isfinite(cols.float_(p)).any() for p in post_names
    )
    if has_post:
        for cat, p in zip(CATEGORY_NAMES, post_names, strict=True):
            tt, yy = _thin(*_gap_broken(t, cols.float_(p), MAX_GAP_S), n_columns, span, ordered)
            ax_c.plot(tt, yy, color=KIND_COLOURS[cat], lw=1.0, marker=".", ms=2,
                      label=KIND_LABELS[cat])
        ax_c.axhline(0.5, color="0.5", lw=0.6, ls=":")
        _legend(ax_c, 4)
    else:
        _missing(ax_c, "posteriors")
    ax_c.set_ylim(-0.05, 1.05)
    ax_c.set_ylabel("P(model | obs)")
    _panel_label(ax_c, "(C) motion model probabilities")

    # (D) progress of the most probable model
    s_names = [f"s_curr_{m}" for m in LIFT_KINDS]
    if has_post and all(s in cols for s in s_names):
        # The most probable of the four categories; when it is "other" no model's
        # progress means anything and nothing is drawn.
        post = np.stack([cols.float_(p) for p in post_names], axis=1)
        prog = np.stack([cols.float_(s) for s in s_names], axis=1)
        ok = np.isfinite(post).any(axis=1)
        best = np.argmax(np.where(np.isfinite(post), post, -1.0), axis=1)
        for j, kind in enumerate(LIFT_KINDS):
            y = np.where(ok & (best == j), prog[:, j], np.nan)
            tt, yy = _thin(*_gap_broken(t, y, MAX_GAP_S), n_columns, span, ordered)
            ax_d.plot(tt, yy, color=KIND_COLOURS[kind], lw=1.0, marker=".", ms=2,
                      label=KIND_LABELS[kind])
        _legend(ax_d, 3)
    else:
        _missing(ax_d, "progress estimates")
    ax_d.set_ylim(-0.03, 1.03)
    ax_d.set_ylabel("$s_{curr}$")
    _panel_label(ax_d, "(D) progress of the most probable model")

    # (E) control signals
    action = cols.int_("action").astype(np.float64)
    steps = step_changes(action) if ordered else np.arange(n)
    # Not snapped to the pixel grid, as the step line through every tick never was
    # (matplotlib snaps only short paths): the same picture as before the thinning.
    ax_e.plot(t[steps], action[steps], color="black", lw=1.0, drawstyle="steps-post",
              label="action", snap=False)
    _held(ax_e, t, cols.bool_("lock_left"), (0.4, 0.65), _LEFT, "left held", ordered)
    _held(ax_e, t, cols.bool_("lock_right"), (0.05, 0.3), _RIGHT, "right held", ordered)
    ax_e.set_yticks([0.175, 0.525, 1, 2, 3, 4],
                    ["R held", "L held", *[a.replace("_", " ") for a in ACTION_NAMES]])
    ax_e.set_ylim(-0.05, 4.3)
    _legend(ax_e, 3)
    ax_e.set_xlabel("time (s)")
    _panel_label(ax_e, "(E) control signals")

    for ax in (ax_b, ax_c, ax_d, ax_e):
        _shade_lifts(ax, inside, t, start)
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.set_xlim(float(t[0]), float(t[-1]) if n > 1 else 1.0)
    for ax in (ax_b, ax_c, ax_d):
        ax.tick_params(labelbottom=False)
    for t_mark, label in markers:
        x = float(t_mark - t_abs[0])
        if not 0.0 <= x <= float(t[-1]):
            continue
        for ax in (ax_b, ax_c, ax_d, ax_e):
            ax.axvline(x, color=_MARKER, lw=0.9, ls="--")
        ax_b.annotate(label, (x, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -2),
                      textcoords="offset points", va="top", fontsize=6, color=_MARKER)
    return fig
