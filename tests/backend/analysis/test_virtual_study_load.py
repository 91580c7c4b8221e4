"""The virtual study with both cores busy: two CPU-bound processes started here (and
bounded: they end by themselves after 15 minutes) run beside a short study, which must
pass with complete trials. Before the worker's commands were answered and a sped-up
simulation was paced by the server, this failed with "the worker did not answer the
calibration request" or "the worker did not start pec"."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from backend.analysis.virtual_study import VirtualStudyConfig, run, script_duration_s

pytestmark = pytest.mark.slow

HOG = "import time\nend = time.monotonic() + 900\nwhile time.monotonic() < end:\n    pass\n"


@pytest.mark.timeout(1500)  # slower by design under load; it must pass, not be quick
def test_a_short_virtual_study_passes_with_both_cores_busy(tmp_path: Path) -> None:
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(os.cpu_count() or 2)]
    try:
        cfg = VirtualStudyConfig(out=tmp_path / "vs", participants=1, data_participants=2,
                                 eumc=1, seed=9, rates=("paper-rates",), margin_s=2.0,
                                 model_evaluation=False)
        report = run(cfg, log=lambda _m: None)
        assert all(h.poll() is None for h in hogs), "the load ended before the study"
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    assert sorted(t.controller for t in report.trials) == ["eumc", "pec", "umc"]
    expected = round((script_duration_s(cfg.eval_seed(0), cfg.eval_script) + 2.0) * 100)
    for t in report.trials:
        assert t.ticks == expected and t.gaps == 0, t
    assert (cfg.out / "paper-rates" / "performance.csv").stat().st_size > 0
