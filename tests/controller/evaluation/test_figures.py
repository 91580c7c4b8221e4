"""Figures render offscreen to non-empty PNGs of the documented size and to valid SVG."""

from __future__ import annotations

import io
import struct
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from controller.evaluation.figures import onset_to_lock_figure, peak_torque_figure
from controller.evaluation.lifts import lifts_from_truth
from controller.evaluation.rendering import RenderedFigure, render_figure
from controller.evaluation.study import RecordingEvaluation
from controller.evaluation.timeline import confidence_ellipse, controller_output_figure
from controller.tick_record import Action

from .tick_builder import TickBuilder, lifting_recording

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def check(fig: RenderedFigure, width: int, height: int, dpi: int = 100) -> None:
    assert fig.png.startswith(PNG_MAGIC)
    w, h = struct.unpack(">II", fig.png[16:24])  # the IHDR chunk
    assert (w, h) == (width, height) == (fig.width_px, fig.height_px)
    pixels = imread(io.BytesIO(fig.png))
    assert pixels.shape[:2] == (height, width)
    assert float(pixels[..., :3].std()) > 0.01  # something was drawn
    root = ET.fromstring(fig.svg)
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    view = [float(v) for v in root.attrib["viewBox"].split()]
    assert view[2:] == pytest.approx([width * 72 / dpi, height * 72 / dpi])  # in pt


@pytest.fixture(scope="module")
def study() -> list[RecordingEvaluation]:
    return [
        lifting_recording("1", "pec", good=True, intent=False),
        lifting_recording("1", "umc", good=False),
        lifting_recording("1", "eumc", good=True),
    ]


def test_peak_torque_scatter(study: list[RecordingEvaluation]) -> None:
    panels = render_figure(peak_torque_figure(study))
    check(panels, 1200, 420)
    single = render_figure(peak_torque_figure(study, controllers=["umc"], layout="single"))
    check(single, 400, 420)
    with pytest.raises(ValueError):
        peak_torque_figure(study, layout="grid")  # type: ignore[arg-type]


def test_onset_to_lock_histogram(study: list[RecordingEvaluation]) -> None:
    check(render_figure(onset_to_lock_figure(study)), 900, 360)
    check(render_figure(onset_to_lock_figure(study, dpi=50)), 450, 180, dpi=50)


def test_empty_study_still_renders() -> None:
    check(render_figure(peak_torque_figure([])), 400, 420)
    check(render_figure(onset_to_lock_figure([])), 900, 360)


def test_rendering_is_deterministic_and_saves(
    study: list[RecordingEvaluation], tmp_path: Path
) -> None:
    a = render_figure(peak_torque_figure(study))
    b = render_figure(peak_torque_figure(study))
    assert a.png == b.png and a.svg == b.svg
    png, svg = a.save(tmp_path / "out" / "peaks")
    assert png.read_bytes() == a.png and svg.name == "peaks.svg"


@dataclass(frozen=True)
class FakeModel:
    name: str
    mean: np.ndarray
    cov: np.ndarray


class FakeModelSet:
    """Stands in for `controller.intent.motion_model.ModelSet`: `.ordered()` models."""

    def ordered(self) -> tuple[FakeModel, ...]:
        s = np.linspace(0.0, 1.0, 101)
        bump = np.radians(90.0) * np.sin(np.pi * s)
        cov = np.tile(np.diag([0.01, 0.02]), (101, 1, 1))
        return tuple(
            FakeModel(name, np.stack([bump * a, bump * b], axis=1), cov)
            for name, a, b in (("squat", 1.0, 1.0), ("stoop_left", 1.0, 0.7),
                               ("stoop_right", 0.7, 1.0))
        )


def recording_with_angles(with_posteriors: bool) -> dict[str, np.ndarray]:
    b = TickBuilder(800)
    for i, kind in enumerate(("squat", "stoop_left")):
        lf = b.lift(i, kind, 100 + 350 * i, 349 + 350 * i)  # type: ignore[arg-type]
        bump = np.radians(85.0) * np.sin(np.linspace(0.0, np.pi, 250))
        b.cols["q_left"][lf.ticks] = bump
        b.cols["q_right"][lf.ticks] = bump * (1.0 if kind == "squat" else 0.7)
        b.run(lf.start + 40, lf.correct_action)
        if with_posteriors:
            for k in range(lf.start + 20, lf.start + 120, 10):
                b.posterior(k, kind, min(1.0, (k - lf.start) / 60))
                b.cols[f"s_curr_{kind}"][k] = (k - lf.start) / 250
    b.cols["q_left"][np.isnan(b.cols["q_left"])] = 0.0
    b.cols["q_right"][np.isnan(b.cols["q_right"])] = 0.0
    b.run(700, Action.LOCK_RIGHT)
    return b.columns()


def test_controller_output_figure_with_models() -> None:
    cols = recording_with_angles(with_posteriors=True)
    fig = controller_output_figure(cols, 50, 750, models=FakeModelSet(),
                                   lifts=lifts_from_truth(cols), title="two lifts")
    check(render_figure(fig), 1300, 800)


def test_controller_output_figure_without_posteriors_or_models() -> None:
    cols = recording_with_angles(with_posteriors=False)  # a PEC recording
    check(render_figure(controller_output_figure(cols, dpi=40)), 520, 320, dpi=40)
    with pytest.raises(ValueError, match="no ticks"):
        controller_output_figure(cols, 10, 10)
    with pytest.raises(ValueError, match="progress points"):
        controller_output_figure(cols, progress_points=(1.5,))


def test_confidence_ellipse_axes() -> None:
    w, h, angle = confidence_ellipse(np.zeros(2), np.diag([4.0, 1.0]))
    k = 5.991464547107979  # chi-square 95 % quantile, 2 degrees of freedom
    assert (w, h) == (pytest.approx(2 * np.sqrt(4.0 * k)), pytest.approx(2 * np.sqrt(k)))
    assert angle == pytest.approx(0.0) or angle == pytest.approx(180.0)
    with pytest.raises(ValueError):
        confidence_ellipse(np.zeros(2), np.zeros((2, 2)))


def test_controller_output_figure_draws_markers_inside_the_stretch() -> None:
    cols = recording_with_angles(with_posteriors=False)
    t = cols["t"]
    inside, outside = float(t[300]), float(t[20])
    fig = controller_output_figure(cols, 50, 750,
                                   markers=[(inside, "box dropped"), (outside, "too early")])
    ax_b = fig.axes[1]
    labels = [a.get_text() for a in ax_b.texts]
    assert "box dropped" in labels and "too early" not in labels
    # A line on each time panel at the marker, on the stretch's own time axis.
    want = inside - float(t[50])
    for ax in fig.axes[1:5]:
        xs = [ln.get_xdata()[0] for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        assert xs == [pytest.approx(want)]


def long_trial(n: int = 20_000) -> dict[str, np.ndarray]:
    """A 200 s trial: noisy hip angles with one tick's spike, posteriors every tick,
    two locks, and a gap where the controller computed nothing."""
    rng = np.random.default_rng(5)
    b = TickBuilder(n)
    b.cols["q_left"][:] = np.radians(5.0 + rng.normal(0.0, 1.0, n))
    b.cols["q_right"][:] = np.radians(5.0 + rng.normal(0.0, 1.0, n))
    b.cols["q_left"][n * 5 // 8] = np.radians(60.0)
    p = rng.uniform(0.0, 1.0, n)  # `TickBuilder.posterior` at every tick
    for cat in ("squat", "stoop_left", "stoop_right", "other"):
        b.cols[f"post_{cat}"][:] = p if cat == "squat" else (1.0 - p) / 3.0
    for cat in ("squat", "stoop_left", "stoop_right", "other"):
        b.cols[f"post_{cat}"][n * 2 // 5:n * 9 // 20] = np.nan
    b.run(n * 3 // 20, Action.LOCK_BOTH)
    b.run(n * 3 // 20 + 100, Action.NO_LOCK)
    b.run(n * 3 // 4, Action.LOCK_LEFT)
    return b.columns()


def test_a_long_trial_is_drawn_from_few_samples_that_keep_every_peak() -> None:
    cols = long_trial()
    fig = controller_output_figure(cols, dpi=40)
    ax_b, ax_c, _ax_d, ax_e = fig.axes[1:5]
    t = cols["t"] - cols["t"][0]
    for line, q in zip(ax_b.get_lines(), (cols["q_left"], cols["q_right"]), strict=True):
        y = np.asarray(line.get_ydata(), dtype=np.float64)
        assert y.size < 0.5 * q.size  # at most four samples a column
        assert float(np.nanmax(y)) == float(np.degrees(q).max())
        assert float(np.nanmin(y)) == float(np.degrees(q).min())
    squat = ax_c.get_lines()[0]
    y = np.asarray(squat.get_ydata(), dtype=np.float64)
    assert y.size < 0.5 * t.size and int(np.isnan(y).sum()) == 1  # the gap stays one break
    # The action steps where it changes; the lock strips span the held ticks.
    action = ax_e.get_lines()[0]
    assert list(action.get_ydata()) == [float(a) for a in (
        Action.NO_LOCK, Action.LOCK_BOTH, Action.NO_LOCK, Action.LOCK_LEFT, Action.LOCK_LEFT)]
    left, right = (c for c in ax_e.collections if c.get_label() in ("left held", "right held"))
    spans = [(float(p.vertices[:, 0].min()), float(p.vertices[:, 0].max()))
             for p in left.get_paths()]
    assert spans == [pytest.approx((t[3_000], t[3_029])), pytest.approx((t[15_000], t[15_029]))]
    assert len(right.get_paths()) == 1
    check(render_figure(fig), 520, 320, dpi=40)


def test_a_figure_draws_the_same_whichever_format_comes_first() -> None:
    """Each format is drawn when asked for; a laid-out figure (`tight_layout`, as the
    muscle figures are) is drawn without its layout pass, in either order."""
    from controller.evaluation.muscle_figures import envelope_cycle_figure

    def figure() -> RenderedFigure:
        cycles = {"umc": {"n": 2, "mean": np.linspace(0.0, 1.0, 303).reshape(101, 3),
                          "sd": np.full((101, 3), 0.05)}}
        # Small (dpi 30): what is compared is the order, not the picture.
        return render_figure(envelope_cycle_figure(cycles, ["a", "b", "c"], "MVC", dpi=30))

    png_first, svg_first = figure(), figure()
    png = png_first.png
    assert svg_first.svg == png_first.svg and svg_first.png == png


def test_line_markers_draw_without_a_warning() -> None:
    import warnings

    study = [lifting_recording("1", name, good=True, intent=False)
             for name in ("springs_free", "no_exoskeleton")]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for layout in ("panels", "single"):
            check(render_figure(peak_torque_figure(study, layout=layout)),
                  400 * (2 if layout == "panels" else 1), 420)
