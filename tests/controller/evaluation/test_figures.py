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

from controller.evaluation import (
    RecordingEvaluation,
    RenderedFigure,
    controller_output_figure,
    lifts_from_truth,
    onset_to_lock_figure,
    peak_torque_figure,
    render_figure,
)
from controller.evaluation.timeline import confidence_ellipse
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
