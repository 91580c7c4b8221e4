"""`exostudy personalisation`: its defaults are the modules' own, and its options reach
the study's configuration (a bad one named)."""

from __future__ import annotations

import pytest

from backend.cli import build_parser
from backend.personalisation_cli import DEFAULTS, config
from controller.evaluation.personalisation import PersonalisationConfig, model_controllers
from controller.evaluation.working_day import DEFAULT_BLOCKS
from controller.intent.learned_priors import DEFAULT_FORGETTING, DEFAULT_PSEUDO_COUNT
from controller.intent.personal_models import DEFAULT_TAU


def test_defaults_are_the_modules() -> None:
    assert {"controllers": ",".join(model_controllers()), "tau": DEFAULT_TAU,
                        "pseudo_count": DEFAULT_PSEUDO_COUNT,
                        "forgetting": DEFAULT_FORGETTING, "day_blocks": DEFAULT_BLOCKS} == DEFAULTS
    args = build_parser().parse_args(["personalisation", "--out", "x"])
    assert config(args) == PersonalisationConfig()


def test_options_reach_the_configuration() -> None:
    args = build_parser().parse_args([
        "personalisation", "--out", "x", "--participants", "5", "--seeds", "4,9",
        "--controllers", "umc", "--demo-counts", "0,5", "--priors-with", "5", "--tau", "2"])
    cfg = config(args)
    assert (cfg.participants, cfg.seeds, cfg.controllers, cfg.demo_counts, cfg.priors_with,
            cfg.tau) == (5, (4, 9), ("umc",), (0, 5), 5, 2.0)
    bad = build_parser().parse_args(["personalisation", "--out", "x", "--seeds", "1,a"])
    with pytest.raises(ValueError, match="--seeds"):
        config(bad)
