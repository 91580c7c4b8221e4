"""Benchmark of the result figures: CPU seconds to build and draw each.

Run: `.venv/bin/python bench/bench_figures.py` (about a minute).

1. The five-panel controller output of a whole 200 s trial at 100 Hz (the simulated
   paper protocol through the E-UMC, about 19,000 ticks), as `GET
   /api/trials/{id}/figures/timeline.png` draws it: built, then one format. Beside it
   the same figure drawn as it was before its lines were thinned
   (`controller.evaluation.decimation`), its lock strips drawn as spans and its formats
   drawn on demand: every sample of every line, both formats for every request.
2. The muscle envelope figure of twelve channels and four conditions (a `tight_layout`
   figure: it used to be drawn once more, rendering nothing, before each format).

CPU seconds of this process (`time.process_time`), best of three, so other work on the
machine moves the figures less than wall time would; the load average is recorded.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from record import load_average, record  # noqa: E402

from controller.evaluation import timeline  # noqa: E402
from controller.evaluation.muscle_activity import LABELS  # noqa: E402
from controller.evaluation.muscle_figures import envelope_cycle_figure  # noqa: E402
from controller.evaluation.paper_protocol import protocol_seed  # noqa: E402
from controller.evaluation.rendering import render_figure  # noqa: E402


def best_cpu(n: int, fn: Callable[[], object]) -> float:
    """Shortest of `n` CPU-time runs of `fn`, seconds."""
    best = float("inf")
    for _ in range(n):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    load = load_average()
    trials, models, _utilities = protocol_seed(1, 1, 1, 2)
    cols, ev = next((c, e) for c, e in trials if e.controller == "eumc")
    lifts = [o.lift for o in ev.lifts]

    def output(fmt: str) -> Callable[[], object]:
        def draw() -> object:
            fig = render_figure(timeline.controller_output_figure(cols, models=models,
                                                                  lifts=lifts))
            return fig.png if fmt == "png" else fig.svg
        return draw

    def as_before() -> object:
        # Every sample drawn (no column fits four times the ticks) and both formats.
        per_pixel = timeline.COLUMNS_PER_PIXEL
        timeline.COLUMNS_PER_PIXEL = 10_000
        try:
            fig = render_figure(timeline.controller_output_figure(cols, models=models,
                                                                  lifts=lifts))
            return fig.png, fig.svg
        finally:
            timeline.COLUMNS_PER_PIXEL = per_pixel

    rng = np.random.default_rng(1)
    cycles = {c: {"n": 8, "mean": rng.random((101, len(LABELS))),
                  "sd": 0.1 * rng.random((101, len(LABELS)))}
              for c in ("umc", "pec", "springs_free", "no_exoskeleton")}

    def envelope(fmt: str) -> Callable[[], object]:
        def draw() -> object:
            fig = render_figure(envelope_cycle_figure(cycles, list(LABELS), "MVC"))
            return fig.png if fmt == "png" else fig.svg
        return draw

    output("png")()  # fonts and caches
    rows: list[list[object]] = [
        [f"controller output, {len(cols)} ticks: one format as a request draws it (PNG)",
         round(best_cpu(3, output("png")), 3)],
        ["the same, SVG", round(best_cpu(3, output("svg")), 3)],
        ["the same, every sample drawn, both formats (as every request drew it before)",
         round(best_cpu(3, as_before), 3)],
        [f"muscle envelopes, {len(LABELS)} channels x 4 conditions: PNG",
         round(best_cpu(3, envelope("png")), 3)],
        ["the same, SVG", round(best_cpu(3, envelope("svg")), 3)],
    ]
    for label, seconds in rows:
        print(f"{seconds:7.3f} s CPU  {label}")
    path = record("figures", "python bench/bench_figures.py", ["figure", "CPU s (best of 3)"],
                  rows, load, note="build and draw, this process's CPU time")
    print(f"written {path}")


if __name__ == "__main__":
    main()
