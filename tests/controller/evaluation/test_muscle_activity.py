"""The virtual cohort's muscle activity against its known truth: the reduction recovered
from simulated sEMG (generation, the processing chain, MVC normalisation, per-lift
outcomes) equals the reduction of the activation that generated it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.config import ControllerConfig
from controller.controllers import registry
from controller.controllers.factory import make_from_spec
from controller.controllers.spec import ControllerSpec
from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import CohortConfig, simulate_participant, trial_recording
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import Lift
from controller.evaluation.muscle_activity import (
    LABELS,
    OUTCOMES,
    ParticipantMuscles,
    SessionEmg,
    lift_spans,
    lift_trial,
    recording_lifts,
)
from controller.intent.motion_model import ModelSet
from controller.runner.replay import AngleRecording, replay_columns
from controller.sim.participant import VirtualParticipant

EXTENSORS = [c for c in LABELS if c.startswith(("erector", "gluteus", "biceps"))]
#: Stated tolerances of the recovered reduction (percentage points, per participant of
#: ten lifts): mean and iEMG average the envelope's ripple out; the peak picks its
#: largest upward excursion, a noisier estimate.
TOL_MEAN_PP = 3.0
TOL_PEAK_PP = 8.0


def _reduction(a: float, base: float) -> float:
    return 100.0 * (1.0 - a / base)


@pytest.mark.parametrize("seed", [7, 9])
def test_recovered_reduction_matches_the_activation_truth(seed: int) -> None:
    p = VirtualParticipant.from_seed(seed)
    rec, human = lift_trial(p, p.seed, "squat-sequence", 0)
    lifts = recording_lifts(rec)
    assert len(lifts) == 10
    s = SessionEmg(p)
    base = s.condition("no_exoskeleton", lifts, human, None)
    # A known support: 40 % of the wearer's extension moment on each side.
    aided = s.condition("umc", lifts, human, 0.4 * np.maximum(human, 0.0))
    for outcome in OUTCOMES:
        tol = TOL_PEAK_PP if outcome == "peak" else TOL_MEAN_PP
        for ch in LABELS:
            got = _reduction(aided.emg["all"][outcome][ch], base.emg["all"][outcome][ch])
            true = _reduction(aided.truth["all"][outcome][ch], base.truth["all"][outcome][ch])
            assert abs(got - true) < tol, (outcome, ch, got, true)
    for ch in EXTENSORS:
        # The support really lowers the extensors (the check is not vacuous) ...
        assert _reduction(aided.truth["all"]["mean"][ch], base.truth["all"]["mean"][ch]) > 15
        # ... and normalisation to the simulated MVC recovers activation itself, up to
        # the MVC reference's own sampling error: the largest 0.5 s average of a 3 s
        # hold lies 0-15 % above full activation's mean (a per-channel scale, which
        # reductions, being ratios, do not see).
        for c in (base, aided):
            ratio = c.emg["all"]["mean"][ch] / c.truth["all"]["mean"][ch]
            assert 0.85 < ratio < 1.02, (ch, ratio)
    assert aided.peak_torque_nm > 10.0 and base.peak_torque_nm == 0.0
    assert len(aided.cycle[LABELS[0]]) == 101
    # Tasks: this script has squats only.
    assert np.isnan(aided.truth["stoop"]["mean"][LABELS[0]])
    assert aided.truth["squat"] == aided.truth["all"]


def test_a_condition_without_the_exoskeleton_gets_no_torque() -> None:
    p = VirtualParticipant.from_seed(3)
    rec, human = lift_trial(p, p.seed, "squat-sequence", 0)
    lifts = recording_lifts(rec)
    s = SessionEmg(p, emg=False)
    assert not registry.exoskeleton_worn("no_exoskeleton")
    given = s.condition("no_exoskeleton", lifts, human, np.full_like(human, 30.0))
    none = s.condition("no_exoskeleton", lifts, human, None)
    assert given.truth == none.truth and given.peak_torque_nm == 0.0
    worn = s.condition("umc", lifts, human, np.full_like(human, 30.0))
    lumbar = "erector_spinae_lumbar_left"
    assert worn.truth["all"]["mean"][lumbar] < none.truth["all"]["mean"][lumbar]
    assert given.emg == {} and given.cycle == {}
    back = ParticipantMuscles.from_dict(
        {"mvc_v": s.result().mvc_v, "emg": False,
         "conditions": {"umc": {**worn.__dict__}}})
    assert back.conditions["umc"] == worn


def test_never_locking_baselines_give_no_torque_in_a_replay() -> None:
    # Why the cohort skips the baselines' replay: unlocked, the spring gives nothing.
    p = VirtualParticipant.from_seed(4)
    full = trial_recording(p, p.seed, "squat-sequence", 0)
    k = 900
    assert full.activity is not None and full.lift_index is not None
    rec = AngleRecording(full.t[:k], full.q[:k], full.activity[:k], full.lift_index[:k])
    for name in registry.baselines():
        cols = TickData.of(replay_columns(rec, make_from_spec(
            ControllerSpec(name, ControllerConfig()))))
        assert not cols.bool_("lock_left").any() and not cols.bool_("lock_right").any()
        torque = np.concatenate([cols.float_("torque_left"), cols.float_("torque_right")])
        assert np.all(np.nan_to_num(torque) == 0.0)


def test_lift_trial_is_the_cohort_recording_with_its_moments() -> None:
    p = VirtualParticipant.from_seed(5)
    rec, human = lift_trial(p, p.seed, "squat-sequence", 1)
    ref = trial_recording(p, p.seed, "squat-sequence", 1)
    assert np.array_equal(rec.q, ref.q) and rec.activity == ref.activity
    assert human.shape == (rec.t.size, 2) and human.max() > 50.0


def test_lift_spans_pad_clip_and_merge() -> None:
    lifts = [Lift(0, "squat", 5, 20), Lift(1, "squat", 30, 40), Lift(2, "stoop_left", 80, 97)]
    assert lift_spans(lifts, 100, 6) == [(0, 47), (74, 100)]
    assert lift_spans(lifts, 100, 0) == [(5, 21), (30, 41), (80, 98)]


@pytest.mark.slow
def test_the_cohort_records_every_condition_with_emg(default_sets: tuple[Path, Path]) -> None:
    models_path, folder = default_sets
    models = ModelSet.load(models_path)
    utilities = UtilitySet.load(next(folder.glob("utilities-*.json")))
    cfg = CohortConfig(participants=2, controllers=("pec",), emg=True)
    res = simulate_participant(cfg, 0, models, utilities)
    assert res.muscles is not None and res.muscles.emg
    conds = res.muscles.conditions
    assert set(conds) == {"pec", *registry.baselines()}
    assert all(v > 0 for v in res.muscles.mvc_v.values())
    assert conds["pec"].peak_torque_nm > 5.0
    assert all(conds[b].peak_torque_nm == 0.0 for b in registry.baselines())
    assert all(c.n_lifts == 20 for c in conds.values())
    lumbar = "erector_spinae_lumbar_left"
    assert (conds["pec"].truth["all"]["mean"][lumbar]
            < conds["no_exoskeleton"].truth["all"]["mean"][lumbar])
    # Without the flag nothing of it is computed.
    plain = simulate_participant(CohortConfig(participants=2, controllers=("pec",)), 0,
                                 models, utilities)
    assert plain.muscles is None and plain.metrics == res.metrics
