"""The virtual study's driver: the length of a script repetition, which sets every timed
recording and trial, is the simulator's own (computed without the hip moments, and
kept)."""

from __future__ import annotations

import pytest

from backend.analysis.virtual_study_driver import script_duration_s
from controller.sim.exoskeleton import SimulatedExoskeleton


@pytest.mark.parametrize("script", ["paper-evaluation", "lift-evaluation", "squat-sequence",
                                    "stoop-sequence", "walking"])
@pytest.mark.parametrize("seed", [1, 7, 1_000_003])
def test_a_scripts_duration_is_the_simulators(script: str, seed: int) -> None:
    assert script_duration_s(seed, script) == SimulatedExoskeleton(seed=seed,
                                                                   script=script).duration
