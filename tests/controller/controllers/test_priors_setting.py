"""Priors as a per-trial controller setting: one typed record in the specification,
equal priors by default (today's controller), unsafe priors refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from controller.config import ControllerConfig, SettingError
from controller.controllers.factory import make_from_spec
from controller.controllers.spec import ControllerSpec
from controller.controllers.umc import UMC
from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import trial_recording
from controller.intent.learned_priors import learn_from_confirmed
from controller.intent.motion_model import ModelSet
from controller.intent.prior_safety import PriorBounds
from controller.runner.replay import replay_columns
from controller.sim.participant import VirtualParticipant


@pytest.fixture(scope="module")
def docs(default_sets: tuple[Path, Path]) -> tuple[dict[str, object], dict[str, object]]:
    from backend import bootstrap
    models, folder = default_sets
    return (ModelSet.load(models).to_json(),
            UtilitySet.load(bootstrap.utilities_path(folder, 25.0)).to_json())


def test_default_spec_is_unchanged_on_the_wire() -> None:
    spec = ControllerSpec("pec")
    assert "priors" not in spec.to_config()
    assert spec.settings.priors == (0.25, 0.25, 0.25, 0.25)


def test_priors_record_sets_the_settings_and_round_trips(docs: tuple) -> None:
    bounds = PriorBounds.for_table(np.asarray(docs[1]["utilities_nm2"]))
    rec = learn_from_confirmed(["stoop_left", "stoop_right"] * 30 + ["other"] * 20, bounds,
                               version="P1-w3")
    spec = ControllerSpec("umc", models=docs[0], utilities=docs[1], priors=rec)
    assert spec.settings.priors == rec.values
    wire = json.loads(json.dumps(spec.to_config()))
    again = ControllerSpec.from_config("umc", wire)
    assert again.priors == rec and again.settings == spec.settings
    ctl = make_from_spec(again)
    assert isinstance(ctl, UMC) and ctl.intent.priors.tolist() == list(rec.values)


def test_conflicting_or_broken_priors_are_named(docs: tuple) -> None:
    bounds = PriorBounds.for_table(np.asarray(docs[1]["utilities_nm2"]))
    rec = learn_from_confirmed(["squat"] * 5, bounds)
    with pytest.raises(SettingError, match="priors: settings ask for priors"):
        ControllerSpec("umc", ControllerConfig(priors=(0.1, 0.3, 0.3, 0.3)), docs[0],
                       None, docs[1], None, rec)
    with pytest.raises(SettingError, match=r"priors: not an exostudy\.learned_priors"):
        ControllerSpec.from_config("umc", {"models": docs[0], "utilities": docs[1],
                                           "priors": {"format": "x"}})


def test_umc_refuses_priors_that_could_add_locks(docs: tuple) -> None:
    spec = ControllerSpec("umc", ControllerConfig(priors=(0.05, 0.65, 0.05, 0.25)),
                          models=docs[0], utilities=docs[1])
    with pytest.raises(SettingError, match=r"priors: .*could make the controller lock"):
        make_from_spec(spec)
    ok = ControllerSpec("eumc", ControllerConfig(priors=(0.1, 0.3, 0.3, 0.3)),
                        models=docs[0], utilities=docs[1])
    eumc = make_from_spec(ok)
    assert isinstance(eumc, UMC) and eumc.intent.priors.tolist() == [0.1, 0.3, 0.3, 0.3]


def test_learned_priors_reach_the_posteriors_of_the_running_controller(docs: tuple) -> None:
    rec = trial_recording(VirtualParticipant.from_seed(4), 4, "stoop-sequence", 0)
    base = replay_columns(rec, make_from_spec(
        ControllerSpec("umc", models=docs[0], utilities=docs[1])))
    pri = (0.1, 0.3, 0.3, 0.3)
    moved = replay_columns(rec, make_from_spec(
        ControllerSpec("umc", ControllerConfig(priors=pri), models=docs[0],
                       utilities=docs[1])))
    ran = base["controller_ran"]
    k = np.flatnonzero(ran & (base["p_obs_stoop_left"] > 0.1))[0]
    assert moved["p_obs_stoop_left"][k] == base["p_obs_stoop_left"][k]
    w = np.array([base[f"p_obs_{n}"][k] for n in ("squat", "stoop_left", "stoop_right")])
    other = np.prod(1 - w)
    expect = np.append(w, other) * pri / np.dot(np.append(w, other), pri)
    got = [moved[f"post_{n}"][k] for n in ("squat", "stoop_left", "stoop_right", "other")]
    assert got == pytest.approx(expect.tolist(), rel=1e-12)


def test_umc_and_the_request_check_refuse_priors_below_the_floor(docs: tuple) -> None:
    """[0, 0.3, 0.3, 0.4] satisfies the lock relations but leaves squat unrecognisable:
    the documented floor (0.05) holds in the worker and where a request brings priors."""
    from backend.study.conditions import spec_priors_problem

    spec = ControllerSpec("umc", ControllerConfig(priors=(0.0, 0.3, 0.3, 0.4)),
                          models=docs[0], utilities=docs[1])
    with pytest.raises(SettingError, match=r"squat is 0, below its floor 0\.05"):
        make_from_spec(spec)
    problem = spec_priors_problem(spec)
    assert problem is not None and "below its floor" in problem
    at_floor = ControllerSpec("umc", ControllerConfig(priors=(0.05, 0.3, 0.3, 0.35)),
                              models=docs[0], utilities=docs[1])
    assert spec_priors_problem(at_floor) is None
    assert isinstance(make_from_spec(at_floor), UMC)
