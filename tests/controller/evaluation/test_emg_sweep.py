"""The spring-setting sweep: its stiffness scaling is the actuator's own, and on a tiny
cohort stiffer springs give proportionally more torque and less extensor activation."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.decision.utility_function import UtilitySet
from controller.evaluation.emg_sweep import PREDICTION, SweepConfig, run_sweep, write_outputs
from controller.intent.motion_model import ModelSet
from controller.lowlevel.actuator import PAPER_ACTUATOR, maccepa_torque, max_deflection


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 60.0), st.floats(0.1, 5.0), st.floats(0.0, 2.0))
def test_torque_is_proportional_to_stiffness_and_the_stop_is_not(
        pct: float, factor: float, alpha: float) -> None:
    stiff = replace(PAPER_ACTUATOR, stiffness_n_per_mm=factor * PAPER_ACTUATOR.stiffness_n_per_mm)
    assert max_deflection(pct, stiff) == max_deflection(pct, PAPER_ACTUATOR)
    assert maccepa_torque(alpha, pct, stiff) == pytest.approx(
        factor * maccepa_torque(alpha, pct, PAPER_ACTUATOR), rel=1e-12, abs=1e-12)


def test_config_names_what_it_refuses() -> None:
    with pytest.raises(ValueError, match="precompressions"):
        SweepConfig(precompressions=(120.0,))
    with pytest.raises(ValueError, match="stiffness"):
        SweepConfig(stiffness_factors=(0.0,))
    with pytest.raises(ValueError, match="controllers"):
        SweepConfig(controllers=("springs_free",))


@pytest.mark.slow
def test_a_tiny_sweep(default_sets: tuple[Path, Path], tmp_path: Path) -> None:
    models_path, folder = default_sets
    models = ModelSet.load(models_path)
    utilities = UtilitySet.load(next(folder.glob("utilities-*.json")))
    cfg = SweepConfig(participants=2, controllers=("pec",), precompressions=(25.0,),
                      stiffness_factors=(0.5, 1.0, 2.0))
    rows = run_sweep(cfg, models, lambda _pct: utilities, log=lambda _m: None)
    assert [r.stiffness_factor for r in rows] == [0.5, 1.0, 2.0]
    t = [r.peak_torque_nm[0] for r in rows]
    assert t[1] > 10.0 and t[0] == pytest.approx(0.5 * t[1]) and t[2] == pytest.approx(2 * t[1])
    es = [r.mean_reduction_pct["erector_spinae_lumbar"][0] for r in rows]
    assert 0.0 < es[0] < es[1] < es[2] < 100.0
    assert all(r.n == 2 for r in rows)
    paths = write_outputs(cfg, rows, tmp_path)
    assert {p.name for p in paths} == {"sweep.csv", "sweep.md", "sweep.json", "sweep.png",
                                       "sweep.svg", "README.md"}
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert doc["prediction"] == PREDICTION and len(doc["rows"]) == 3
    assert math.isclose(doc["rows"][1]["stiffness_n_per_mm"], 67.2)
    assert "MODEL PREDICTION" in (tmp_path / "sweep.md").read_text()
    assert np.isfinite(rows[0].mean_reduction_pct["gluteus_maximus"][1])
