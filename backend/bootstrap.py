"""Embedded defaults for a first start: a model set and a utility set from the simulation.

A newcomer's `make run` has no demonstrations yet, so the live controllers would have no
models. The simulated data-collection phase (six virtual participants, as in the paper)
provides them; the reference human dataset provides the utilities. Both are files under
`var/` with their provenance inside, built once and reused.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from controller.decision.utility_function import DEFAULT_OTHER_RULE, UtilitySet, compute_utilities
from controller.intent.motion_model import ModelSet

log = logging.getLogger(__name__)


def ensure_models(path: Path) -> ModelSet:
    """Load the model set at `path`, fitting it from simulated demonstrations if missing."""
    if path.is_file():
        return ModelSet.load(path)
    log.info("fitting the default model set from simulated demonstrations -> %s", path)
    # The simulator (SciPy, the compiled plant) only on a first start: importing it would
    # cost every process that imports the server.
    from controller.sim.demonstrations import simulated_model_set
    models = simulated_model_set()
    with _replacing(path) as tmp:
        models.save(tmp)
    return models


def utilities_path(folder: Path, precompression_pct: float) -> Path:
    """Where the default utility set for a precompression is kept."""
    return folder / f"utilities-sim-p{precompression_pct:g}.json"


def ensure_utilities(path: Path, precompression_pct: float) -> UtilitySet:
    """Load the utility set at `path`, computing it from the reference dataset if missing
    or if it was computed from another version of the dataset or another `other` rule."""
    # The reference dataset's generator (the simulator's activities, SciPy) only when the
    # utilities are checked, not whenever the server is imported; the data themselves
    # only when the utilities must be computed (every server start checks them).
    from controller.sim.human_dataset import reference_dataset, reference_version

    if path.is_file():
        try:
            cached = UtilitySet.load(path)
        except (ValueError, KeyError) as exc:
            log.warning("rebuilding %s: %s", path, exc)
        else:
            if (cached.human_version == reference_version()
                    and cached.meta.get("other_rule") == DEFAULT_OTHER_RULE
                    and cached.precompression_pct == precompression_pct):
                return cached
            log.info("rebuilding %s: computed from other data or rules", path)
    log.info("computing default utilities for %.1f %% precompression -> %s",
             precompression_pct, path)
    human = reference_dataset()
    utilities = compute_utilities(human, precompression_pct)
    with _replacing(path) as tmp:
        utilities.save(tmp)
    return utilities


@contextmanager
def _replacing(path: Path) -> Iterator[Path]:
    """A temporary file of its own beside `path`, renamed onto it when the block ends:
    two servers (or two threads of one) that build the same default at once each write
    their own file, and `path` is always whole (a shared ".tmp" name let one rename the
    other's half-written file, or fail to find its own)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    tmp.chmod(0o644)  # as `write_text` would make it (mkstemp's file is the owner's only)
    try:
        yield tmp
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
