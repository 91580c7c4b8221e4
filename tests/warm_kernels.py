"""Compile the numba kernels once, into their on-disk cache, before the suite starts.

Every kernel is `@njit(cache=True)`: the first process that calls it compiles it and
writes it to `__pycache__` beside its source, and every later process (the xdist
workers, the servers and workers they spawn) loads it from there. On a fresh clone the
cache is empty, and the test processes and the servers they start all compiled the same
kernels at the same moment, each about 20 s of CPU. `make test` runs this module in one
process first, beside the static checks, so that the suite starts with a warm cache.
It runs the paths that compile them: every registered controller built and warmed as
the worker builds it, one virtual participant of the cohort (each controller replayed
over the simulated mechanism, EMG on), and the cohort's rank statistics.

    python -m tests.warm_kernels
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np


def warm() -> None:
    """Call each compiled path once (its results are thrown away)."""
    from backend import bootstrap
    from controller.controllers import registry
    from controller.controllers.factory import make_controller, needs_models
    from controller.emg.processing import EnvelopeStream
    from controller.evaluation.cohort import CohortConfig, simulate_participant
    from controller.evaluation.cohort_stats import wilcoxon_p

    with tempfile.TemporaryDirectory(prefix="exostudy-warm-") as tmp:
        folder = Path(tmp)
        models = bootstrap.ensure_models(folder / "models.json")
        utilities = bootstrap.ensure_utilities(bootstrap.utilities_path(folder, 25.0), 25.0)
        for name in registry.names():
            config = ({"models": models.to_json(), "utilities": utilities.to_json()}
                      if needs_models(name) else {})
            try:
                make_controller(name, config).warm_up()
            except ValueError:
                continue  # needs a calibration first: the cohort below calibrates it
        simulate_participant(CohortConfig(participants=2, seed=1, emg=True), 0,
                             models, utilities)
    wilcoxon_p(np.array([[0.5, -1.0, 2.0, 0.5]]))
    EnvelopeStream(2000.0, 2).push(np.zeros((4, 2)))  # the live strip's causal envelope


if __name__ == "__main__":
    started, cpu = time.monotonic(), time.process_time()
    warm()
    print(f"numba kernels compiled or loaded from their cache in "
          f"{time.monotonic() - started:.1f} s ({time.process_time() - cpu:.1f} s CPU)")
