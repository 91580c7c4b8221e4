"""Benchmark of the result figures: CPU seconds to build and draw each.

Run: `.venv/bin/python bench/bench_figures.py` (about a minute).

1. The five-panel controller output of a whole 200 s trial at 100 Hz (the simulated
   paper protocol through the E-UMC, about 19,000 ticks), as `GET
   /api/trials/{id}/figures/timeline.png` draws it: built, then one format; then both
   formats, as a report writes them; then both with the lines not thinned
   (`controller.evaluation.decimation`), every sample drawn. The same two for the UMC
   run at 100 Hz, whose posteriors and progress (drawn with a marker per sample) fill
   every tick: there the thinning counts.
2. The muscle envelope figure of twelve channels and four conditions, one format per
   request (a `tight_layout` figure: it used to be drawn once more, rendering nothing,
   before each format).

Before this round's changes every request drew both formats (and the muscle figures
each twice): measured on the same machine, a request for the controller output cost
about 1.0 s CPU and one for the muscle envelopes 1.5 to 2 s.

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
from record import load_average, record

from controller.config import ControllerConfig
from controller.evaluation import timeline
from controller.evaluation.cohort import replay_trial, trial_recording
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import Lift
from controller.evaluation.muscle_activity import LABELS
from controller.evaluation.muscle_figures import envelope_cycle_figure
from controller.evaluation.paper_protocol import PAPER_PRECOMPRESSION, protocol_seed
from controller.evaluation.rendering import render_figure
from controller.sim.participant import VirtualParticipant


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
    trials, models, utilities = protocol_seed(1, 1, 1, 2)
    cols, ev = next((c, e) for c, e in trials if e.controller == "eumc")
    lifts = [o.lift for o in ev.lifts]
    rec = trial_recording(VirtualParticipant.from_seed(101), 101, "paper-evaluation", 0)
    fast, fast_ev, _ = replay_trial(
        rec, "umc", ControllerConfig(precompression_pct=PAPER_PRECOMPRESSION).at_rate(100.0),
        models.start_posture(), (models.to_json(), utilities.to_json()), "P01")
    fast_lifts = [o.lift for o in fast_ev.lifts]

    def output(fmt: str) -> Callable[[], object]:
        def draw() -> object:
            fig = render_figure(timeline.controller_output_figure(cols, models=models,
                                                                  lifts=lifts))
            return fig.png if fmt == "png" else fig.svg
        return draw

    def both(trial: TickData = cols, shaded: list[Lift] = lifts) -> object:
        fig = render_figure(timeline.controller_output_figure(trial, models=models,
                                                              lifts=shaded))
        return fig.png, fig.svg

    def unthinned(trial: TickData = cols, shaded: list[Lift] = lifts) -> object:
        # Every sample drawn: no line is longer than four samples a column.
        per_pixel = timeline.COLUMNS_PER_PIXEL
        timeline.COLUMNS_PER_PIXEL = 10_000
        try:
            return both(trial, shaded)
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
        ["the same, both formats", round(best_cpu(3, both), 3)],
        ["the same, both formats, lines not thinned", round(best_cpu(3, unthinned), 3)],
        [f"controller output of the UMC at 100 Hz, {len(fast)} ticks: both formats",
         round(best_cpu(3, lambda: both(fast, fast_lifts)), 3)],
        ["the same, lines not thinned",
         round(best_cpu(3, lambda: unthinned(fast, fast_lifts)), 3)],
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
