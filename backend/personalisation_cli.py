"""`exostudy personalisation`: the virtual personalisation study (population models,
personal models with 0..10 demonstrations per motion, and learned priors on the same
virtual wearers; `controller.evaluation.personalisation`), written as tables, a figure
and the replication report's section. Every option is the study's own setting; the
defaults are the modules' (nothing is tuned)."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from controller.evaluation.personalisation import PersonalisationConfig

#: The modules' defaults, written out so that `exostudy --help` does not import the
#: simulator (tests/backend/test_personalisation_cli.py checks they agree).
DEFAULTS = {"controllers": "umc,eumc", "tau": 5.0, "pseudo_count": 2.5, "forgetting": 0.99,
            "day_blocks": 6}


def _ints(text: str, what: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"{what}: comma-separated whole numbers, got {text!r}") from None


def add_parser(sub: Any) -> None:
    """Register the subcommand on the `exostudy` parser's subparsers."""
    p = sub.add_parser("personalisation", help="virtual personalisation study: population "
                       "against personal models and learned priors, with intervals")
    p.add_argument("--participants", type=int, default=40, help="per seed")
    p.add_argument("--seeds", default="1,2,3", help="comma-separated cohort seeds")
    p.add_argument("--controllers", default=DEFAULTS["controllers"],
                   help="comma-separated, those with motion models")
    p.add_argument("--demo-counts", default="0,3,5,10",
                   help="demonstrations per motion of the personal sets")
    p.add_argument("--priors-with", type=int, default=10,
                   help="the personal (MAP) set also run with learned priors")
    p.add_argument("--tau", type=float, default=DEFAULTS["tau"], help="MAP relevance factor")
    p.add_argument("--pseudo-count", type=float, default=DEFAULTS["pseudo_count"])
    p.add_argument("--forgetting", type=float, default=DEFAULTS["forgetting"])
    p.add_argument("--day-blocks", type=int, default=DEFAULTS["day_blocks"],
                   help="blocks of the stairs-heavy working day")
    p.add_argument("--precompression", type=float, default=25.0, help="%% of 22 mm")
    p.add_argument("--processes", type=int, default=1)
    p.add_argument("--out", required=True)
    p.set_defaults(func=run)


def config(args: argparse.Namespace) -> PersonalisationConfig:
    """The study's configuration from the options (ValueError naming a bad one)."""
    from controller.evaluation.personalisation import PersonalisationConfig

    return PersonalisationConfig(
        participants=args.participants, seeds=_ints(args.seeds, "--seeds"),
        controllers=tuple(c.strip() for c in args.controllers.split(",") if c.strip()),
        demo_counts=_ints(args.demo_counts, "--demo-counts"), priors_with=args.priors_with,
        tau=args.tau, pseudo_count=args.pseudo_count, forgetting=args.forgetting,
        day_blocks=args.day_blocks, precompression_pct=args.precompression)


def run(args: argparse.Namespace) -> int:
    """Simulate and write the outputs."""
    from controller.evaluation.personalisation import simulate_study
    from controller.evaluation.personalisation_report import write_outputs

    cfg = config(args)
    if args.processes < 1:
        raise ValueError("--processes: at least 1")
    load = os.getloadavg()
    t0 = time.monotonic()
    study = simulate_study(cfg, processes=args.processes)
    paths = write_outputs(study, Path(args.out))
    print(f"{len(study.outcomes)} virtual participants in {time.monotonic() - t0:.1f} s "
          f"({args.processes} process(es), load average before {load[0]:.2f}); wrote "
          f"{len(paths)} files to {args.out} (see README.md there)")
    return 0
