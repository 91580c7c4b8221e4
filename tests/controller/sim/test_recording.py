"""True-angle recordings: CSV and in-process arrays, and their speed."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from controller.sim.activity_kinds import ACTIVITIES
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.recording import CSV_COLUMNS, simulate_angles, simulate_to_csv


def test_csv_matches_the_arrays(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    rows = simulate_to_csv(3, "stoop-sequence", out)
    run = simulate_angles(3, "stoop-sequence")
    assert rows == run.t.size
    with out.open() as fh:
        reader = csv.reader(fh)
        assert tuple(next(reader)) == CSV_COLUMNS
        lines = list(reader)
    assert len(lines) == rows
    t = np.array([float(r[0]) for r in lines])
    q = np.array([[float(r[1]), float(r[2])] for r in lines])
    assert np.allclose(t, run.t, atol=0.006)
    assert np.allclose(q, run.q, atol=1e-6)
    assert {r[3] for r in lines} <= set(ACTIVITIES)
    assert [int(r[4]) for r in lines] == run.truth.lift_index.tolist()
    assert sorted({int(r[4]) for r in lines}) == list(range(-1, 10))


def test_angles_are_the_ones_the_exoskeleton_plays() -> None:
    run = simulate_angles(4, "stairs")
    exo = SimulatedExoskeleton(seed=4, script="stairs")
    for k in range(run.t.size):
        s = exo.tick(None)
        assert s.truth is not None
        assert s.truth.activity == run.truth.activity[k]
        assert exo.true_angles() == pytest.approx(tuple(run.q[k]))
    assert exo.finished


def test_paper_protocol_runs_to_its_end_sample_for_sample() -> None:
    # How much faster than real time: bench/bench_simulation.py.
    run = simulate_angles(1, "paper-evaluation")
    exo = SimulatedExoskeleton(seed=1, script="paper-evaluation")
    n = 0
    while not exo.finished:
        exo.tick(None)
        n += 1
    assert n == run.t.size == round(exo.duration / exo.dt)
