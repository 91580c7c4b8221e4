"""UMC, E-UMC and PEC as black boxes: samples in, tick records out.

The wearer is the simulated one (its ground truth labels the lifts); the models are
fitted from simulated demonstrations by the same code a first `make run` uses.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from controller.config import ControllerConfig
from controller.controllers.eumc import EUMC
from controller.controllers.factory import make_controller
from controller.controllers.pec import PEC
from controller.controllers.umc import UMC
from controller.decision.utility_function import UtilitySet
from controller.device.base import Sample, Status
from controller.intent.motion_model import ModelSet
from controller.interface import Controller
from controller.tick_record import Action, TickFlag, TickRecord
from tests.controller.evaluation.tick_builder import closed_loop


@pytest.fixture(scope="module")
def sets(default_sets: tuple[Path, Path]) -> tuple[ModelSet, UtilitySet]:
    from backend import bootstrap
    models, folder = default_sets
    return ModelSet.load(models), UtilitySet.load(bootstrap.utilities_path(folder, 25.0))


def run(ctl: Controller, script: str, seed: int = 11) -> list[TickRecord]:
    return closed_loop(ctl, script, seed)


def calibrated(sets: tuple[ModelSet, UtilitySet], script: str, seed: int) -> EUMC:
    from controller.intent.calibration import calibrate
    from controller.sim.demonstrations import record

    rec = record(seed, script)
    start = sets[0].start_posture()
    cal = calibrate(rec.q[:200], start)
    return EUMC(*sets, ControllerConfig().with_calibration(cal.offset_left, cal.offset_right))


def test_pec_requests_lock_both_exactly_while_the_trigger_holds() -> None:
    ticks = run(PEC(), "squat-sequence")
    ran = [t for t in ticks if t.controller_ran]
    assert len(ran) == len(ticks)  # 100 Hz
    assert all((t.action == Action.LOCK_BOTH) == t.trigger for t in ran)
    assert sum(t.trigger for t in ticks) > 50
    # The hold keeps the command 0.3 s after the last request, never longer.
    last_trigger = -10**9
    for i, t in enumerate(ticks):
        if t.trigger:
            last_trigger = i
        assert t.lock_left == (i - last_trigger < 30)


def test_eumc_never_runs_the_umc_while_the_trigger_is_off(sets) -> None:  # type: ignore[no-untyped-def]
    ticks = run(calibrated(sets, "squat-sequence", 11), "squat-sequence")
    evaluated = [t for t in ticks if not math.isnan(t.post_squat)]
    assert evaluated
    assert all(t.trigger for t in evaluated)
    assert all(t.action == Action.NO_LOCK for t in ticks if t.controller_ran and not t.trigger)


def test_eumc_without_calibration_refuses_to_lock(sets) -> None:  # type: ignore[no-untyped-def]
    ticks = run(EUMC(*sets), "squat-sequence")
    assert all(t.flags & TickFlag.NOT_CALIBRATED for t in ticks)
    assert not any(t.lock_left or t.lock_right for t in ticks)


def test_eumc_locks_both_sides_in_squats(sets) -> None:  # type: ignore[no-untyped-def]
    ticks = run(calibrated(sets, "squat-sequence", 11), "squat-sequence")
    lifts = {t.truth_lift for t in ticks if t.truth_lift >= 0}
    locked = {t.truth_lift for t in ticks if t.truth_lift >= 0 and t.lock_left and t.lock_right}
    assert len(lifts) == 10
    assert len(locked) >= 8, f"squats locked: {sorted(locked)} of {sorted(lifts)}"
    torques = [t.torque_left for t in ticks]
    assert max(torques) > 10.0  # the springs were loaded


def test_umc_posteriors_are_distributions_and_the_action_maximises_eu(sets) -> None:  # type: ignore[no-untyped-def]
    ticks = run(UMC(*sets), "stoop-sequence")
    ran = [t for t in ticks if t.controller_ran]
    assert len(ran) == pytest.approx(len(ticks) / 10, abs=5)  # 10 Hz by default
    for t in ran:
        post = [t.post_squat, t.post_stoop_left, t.post_stoop_right, t.post_other]
        assert sum(post) == pytest.approx(1.0, abs=1e-9)
        eu = [t.eu_no_lock, t.eu_lock_both, t.eu_lock_right, t.eu_lock_left]
        assert t.action == int(np.argmax(eu)) + 1
        for m in ("squat", "stoop_left", "stoop_right"):
            if not getattr(t, f"accepted_{m}"):
                assert getattr(t, f"p_obs_{m}") == 0.0


def test_rates_are_configuration(sets) -> None:  # type: ignore[no-untyped-def]
    ticks = run(UMC(*sets, ControllerConfig().at_rate(100.0)), "squat-sequence")
    ran = [t for t in ticks if t.controller_ran]
    assert len(ran) == len(ticks) - 29  # every tick once the 30-sample window is full


def test_bad_samples_give_flagged_no_lock_ticks(sets) -> None:  # type: ignore[no-untyped-def]
    ctl = PEC()
    good = Sample(seq=0, t=0.0, counts=(3100, 3100, 12900, 12900))
    for bad, flag in [
        (Sample(seq=1, t=0.01, counts=(3100, 3100, 99999, 12900)), TickFlag.BAD_SAMPLE),
        (Sample(seq=2, t=float("nan"), counts=(3100, 3100, 12900, 12900)), TickFlag.BAD_SAMPLE),
        (Sample(seq=3, t=0.03, counts=(3100, 3100, 12900, 12900), status=Status.ENCODER_FAULT),
         TickFlag.DEVICE_FAULT),
        # 170 degrees of hip flexion is not a human hip: a bad encoder reading.
        (Sample(seq=4, t=0.04, counts=(3100 + 7737, 3100, 12900, 12900)), TickFlag.BAD_SAMPLE),
    ]:
        ctl.step(good)
        r = ctl.step(bad)
        assert r.flags & flag, bad
        assert not r.lock_left and not r.lock_right


def test_unknown_controller_and_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="unknown controller 'fuzzy'"):
        make_controller("fuzzy")
    with pytest.raises(ValueError, match="umc_rate_hz"):
        ControllerConfig(umc_rate_hz=0)
    with pytest.raises(ValueError, match="priors"):
        ControllerConfig(priors=(0.5, 0.5, 0.5, 0.5))
    with pytest.raises(ValueError, match="unknown controller setting"):
        ControllerConfig.from_json({"umc_rate": 10})


def test_config_round_trips_through_json() -> None:
    c = ControllerConfig(band=5, priors=(0.1, 0.2, 0.3, 0.4)).with_calibration(0.1, -0.05)
    assert ControllerConfig.from_json(c.to_json()) == c
