"""The entry points built from a decision: one pair per controller, cached on disk
beside the controller's module, found again by the next process."""

from __future__ import annotations

import inspect
import subprocess
import sys
from pathlib import Path

import pytest

from controller.controllers import eumc, pec, umc
from controller.kernel.entry_points import entry_points

ROOT = Path(__file__).resolve().parents[3]

PROBE = """
from controller.config import ControllerConfig
from controller.controllers import pec
pec.PEC(ControllerConfig()).warm_up()
s = pec.COMPILED.step.stats
print(len(s.cache_hits), len(s.cache_misses))
"""


def test_a_decision_must_be_compiled() -> None:
    with pytest.raises(TypeError, match="needs a decision compiled with numba"):
        entry_points(lambda state, data, row: (False, 0, 0))  # type: ignore[arg-type]


def test_each_controller_has_its_own_pair_filed_under_its_module() -> None:
    pairs = [m.COMPILED for m in (pec, umc, eumc)]
    assert len({id(p.step) for p in pairs} | {id(p.batch) for p in pairs}) == 6
    for module in (pec, umc, eumc):
        for kind in ("step", "batch"):
            fn = getattr(module.COMPILED, kind).py_func
            assert fn.__qualname__ == f"decide_{kind}"
            assert inspect.getfile(fn) == module.__file__
            # The copy calls this controller's decision, not the template's stand-in.
            assert fn.__globals__["decide"] is module.decide


def test_the_next_process_loads_the_compiled_tick_from_the_cache() -> None:
    def probe() -> tuple[int, int]:
        out = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, capture_output=True,
                             text=True, check=True, timeout=300)
        hits, misses = out.stdout.split()
        return int(hits), int(misses)

    probe()  # compiles and saves, unless a cache is there already
    assert probe() == (1, 0)
