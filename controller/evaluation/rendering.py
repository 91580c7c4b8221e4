"""Offscreen, deterministic rendering of the evaluation figures to PNG and SVG.

Figures are built as bare `matplotlib.figure.Figure` objects on an Agg canvas, never
through `pyplot`: no global figure registry, no GUI backend, so the backend's request
threads, the CLI and a headless test run can all draw at once (matplotlib's advice for
web servers). Rendering is deterministic: the SVG's date is dropped and its element
ids are salted with a constant, so the same data give the same bytes, which lets a
study's report be diffed and cached.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.typing import RcKeyType

from controller.controllers import registry

#: Pixels per inch of the PNG; figure sizes are given in inches.
DEFAULT_DPI = 100

#: The paper's colours for the motions: squat blue, stoop left green, stoop right red.
KIND_COLOURS: dict[str, str] = {
    "squat": "#1f77b4",
    "stoop_left": "#2ca02c",
    "stoop_right": "#d62728",
    "other": "#7f7f7f",
}
KIND_LABELS: dict[str, str] = {
    "squat": "squat",
    "stoop_left": "stoop left",
    "stoop_right": "stoop right",
    "other": "other",
}
_SPARE_MARKERS = ("D", "v", "P", "X", "*", "<", ">")
_SPARE_COLOURS = ("#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f")

_RC: dict[RcKeyType, Any] = {
    "svg.hashsalt": "exostudy-evaluation",
    "svg.fonttype": "path",
    "font.family": "DejaVu Sans",
    "font.size": 9.0,
}


def controller_marker(name: str, order: int = 0) -> str:
    """The scatter marker a controller registered (`controller.controllers.registry`), else a spare
    one by its order of appearance."""
    reg = registry.lookup(name.lower())
    return (reg.marker if reg is not None and reg.marker
            else _SPARE_MARKERS[order % len(_SPARE_MARKERS)])


def controller_colour(name: str, order: int = 0) -> str:
    """The line colour a controller registered, else a spare one by its order."""
    reg = registry.lookup(name.lower())
    return (reg.colour if reg is not None and reg.colour
            else _SPARE_COLOURS[order % len(_SPARE_COLOURS)])


def new_figure(width_in: float, height_in: float, dpi: int = DEFAULT_DPI) -> Figure:
    """A figure on its own Agg canvas, with the evaluation's style."""
    if not (width_in > 0 and height_in > 0 and dpi > 0):
        raise ValueError(
            f"figure size and dpi must be positive, got {width_in}, {height_in}, {dpi}"
        )
    with matplotlib.rc_context(_RC):
        fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


@dataclass(frozen=True, slots=True)
class RenderedFigure:
    """A figure as PNG and SVG bytes.

    Attributes:
        png: the PNG file's bytes.
        svg: the SVG file's bytes (UTF-8 XML).
        width_px: PNG width in pixels (figure width in inches times dpi).
        height_px: PNG height in pixels.
    """

    png: bytes
    svg: bytes
    width_px: int
    height_px: int

    def save(self, stem: Path | str) -> tuple[Path, Path]:
        """Write `<stem>.png` and `<stem>.svg` (folders created); returns both paths."""
        base = Path(stem)
        base.parent.mkdir(parents=True, exist_ok=True)
        png, svg = base.with_suffix(".png"), base.with_suffix(".svg")
        png.write_bytes(self.png)
        svg.write_bytes(self.svg)
        return png, svg


def render_figure(fig: Figure) -> RenderedFigure:
    """Render `fig` at its own size and dpi. The size is kept exactly (no tight bounding
    box), so callers can lay figures out by their documented pixel size."""
    dpi = float(fig.get_dpi())
    w_in, h_in = fig.get_size_inches()
    with matplotlib.rc_context(_RC):
        png = io.BytesIO()
        fig.savefig(png, format="png", dpi=dpi, metadata={"Software": None})
        svg = io.BytesIO()
        fig.savefig(svg, format="svg", dpi=dpi, metadata={"Date": None})
    return RenderedFigure(png.getvalue(), svg.getvalue(), round(w_in * dpi), round(h_in * dpi))
