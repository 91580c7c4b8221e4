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
import threading
from pathlib import Path
from typing import Any

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.layout_engine import PlaceHolderLayoutEngine
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


class RenderedFigure:
    """A figure as PNG and SVG bytes, each format drawn when first asked for.

    Drawing is most of a figure's cost and a route serves one format per request, so
    the other is never drawn for it; a caller that wants both pays for both, once.
    Safe to read from several threads (one draw at a time per figure).

    Attributes:
        width_px: PNG width in pixels (figure width in inches times dpi).
        height_px: PNG height in pixels.
    """

    __slots__ = ("_bytes", "_fig", "_lock", "height_px", "width_px")

    def __init__(self, fig: Figure, width_px: int, height_px: int) -> None:
        self._fig: Figure | None = fig
        self._bytes: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self.width_px = width_px
        self.height_px = height_px

    def _render(self, fmt: str) -> bytes:
        with self._lock:
            if fmt not in self._bytes:
                assert self._fig is not None  # dropped only once both formats exist
                self._bytes[fmt] = _draw(self._fig, fmt)
                if len(self._bytes) == 2:
                    self._fig = None  # nothing left to draw: let the figure go
            return self._bytes[fmt]

    @property
    def png(self) -> bytes:
        """The PNG file's bytes."""
        return self._render("png")

    @property
    def svg(self) -> bytes:
        """The SVG file's bytes (UTF-8 XML)."""
        return self._render("svg")

    def save(self, stem: Path | str) -> tuple[Path, Path]:
        """Write `<stem>.png` and `<stem>.svg` (folders created); returns both paths."""
        base = Path(stem)
        base.parent.mkdir(parents=True, exist_ok=True)
        png, svg = base.with_suffix(".png"), base.with_suffix(".svg")
        png.write_bytes(self.png)
        svg.write_bytes(self.svg)
        return png, svg


def _draw(fig: Figure, fmt: str) -> bytes:
    """One format of `fig` at its own size and dpi (no tight bounding box)."""
    out = io.BytesIO()
    with matplotlib.rc_context(_RC):
        if fmt == "png":
            fig.savefig(out, format="png", dpi=fig.get_dpi(), metadata={"Software": None})
        else:
            fig.savefig(out, format="svg", dpi=fig.get_dpi(), metadata={"Date": None})
    return out.getvalue()


def render_figure(fig: Figure) -> RenderedFigure:
    """`fig` for rendering at its own size and dpi. The size is kept exactly (no tight
    bounding box), so callers can lay figures out by their documented pixel size.

    A layout already applied (`Figure.tight_layout` leaves a placeholder engine behind)
    is final: the placeholder is removed, so that saving does not draw the whole figure
    once more, rendering nothing, before drawing it (matplotlib does that for any
    figure with a layout engine); the drawing is the same."""
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        with matplotlib.rc_context({"figure.autolayout": False,
                                    "figure.constrained_layout.use": False}):
            fig.set_layout_engine(None)  # None with both rc switches off: no engine
    w_in, h_in = fig.get_size_inches()
    dpi = float(fig.get_dpi())
    return RenderedFigure(fig, round(w_in * dpi), round(h_in * dpi))
