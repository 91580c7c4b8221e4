"""Torques recomputed from the recorded spring deflection."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.evaluation.metrics import evaluate_lift
from controller.evaluation.torques import recompute_torques
from controller.lowlevel.actuator import maccepa_torque

from .tick_builder import TickBuilder


def test_torque_only_while_locked_and_nan_for_missing_deflection() -> None:
    b = TickBuilder(5)
    b.cols["alpha_left"][:] = [0.0, 0.2, 0.4, np.nan, 0.3]
    b.cols["alpha_right"][:] = [0.1, 0.1, 0.1, 0.1, 0.1]
    b.cols["locked_left"][:] = [False, True, True, True, False]
    b.cols["locked_right"][:] = True
    cols = recompute_torques(b.columns(), 25.0)
    left, right = cols.float_("torque_left"), cols.float_("torque_right")
    assert left[0] == 0.0 and left[4] == 0.0  # unlocked
    assert left[1] == pytest.approx(maccepa_torque(0.2, 25.0))
    assert left[2] == pytest.approx(maccepa_torque(0.4, 25.0))
    assert math.isnan(left[3])
    assert right == pytest.approx(np.full(5, maccepa_torque(0.1, 25.0)))
    # A stiffer pretension gives more torque at the same deflection.
    stiffer = recompute_torques(b.columns(), 50.0).float_("torque_left")
    assert stiffer[1] > left[1]


def test_without_mechanism_state_a_deflection_means_locked() -> None:
    b = TickBuilder(3)
    cols = b.columns()
    del cols["locked_left"], cols["locked_right"]
    cols["alpha_left"][:] = [0.001, 0.2, -0.1]
    cols["alpha_right"][:] = 0.0
    left = recompute_torques(cols, 0.0).float_("torque_left")
    assert left[0] == 0.0 and left[2] == 0.0  # within the 0.5 degree deadband / negative
    assert left[1] == pytest.approx(maccepa_torque(0.2, 0.0))


def test_recomputed_torques_feed_the_peaks() -> None:
    b = TickBuilder(300)
    lift = b.lift(0, "squat", 100, 199)
    b.cols["alpha_left"][:] = 0.0
    b.cols["alpha_right"][:] = 0.0
    b.cols["alpha_left"][150] = 0.3
    b.cols["locked_left"][150] = True
    o = evaluate_lift(recompute_torques(b.columns(), 25.0), lift)
    assert o.peak_torque_left == pytest.approx(maccepa_torque(0.3, 25.0))
    assert o.peak_torque_right == 0.0
