"""The compiled control tick through its owners: `KernelController` and the batch replay."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.config import ControllerConfig
from controller.controllers import pec
from controller.controllers.factory import make_controller
from controller.controllers.pec import PEC
from controller.device.base import Sample
from controller.kernel.core import Compiled, Kernel
from controller.kernel.records import ROW, ROW_FIELDS
from controller.runner.replay import AngleRecording, replay_columns
from controller.sim.recording import simulate_angles
from controller.tick_record import TickFlag, TickRecord


@pytest.fixture(scope="module")
def squats() -> AngleRecording:
    run = simulate_angles(5, "squat-sequence")
    return AngleRecording(run.t, run.q, None, None)


def _cfg(default_sets: tuple[Path, Path], **settings: object) -> dict[str, object]:
    models, folder = default_sets
    return {"models_path": str(models), "utilities_path": str(folder / "utilities-sim-p25.json"),
            "settings": settings}


def test_output_row_covers_the_numeric_record_fields_in_order() -> None:
    names = TickRecord.field_names()
    # Everything but identity (seq, times, raw counts), timing and ground truth.
    assert names[names.index("q_raw_left") : names.index("compute_us")] == ROW_FIELDS
    n_numeric = len(names) - 7 - 4
    assert len(ROW_FIELDS) == n_numeric
    assert ROW.names == ROW_FIELDS and all(ROW[n] == np.float64 for n in ROW_FIELDS)


def test_a_count_beyond_64_bits_is_a_bad_sample_not_an_exception() -> None:
    ctl = PEC()
    ctl.step(Sample(seq=0, t=0.0, counts=(3100, 3100, 12900, 12900)))
    r = ctl.step(Sample(seq=1, t=0.01, counts=(3100, 1 << 70, 12900, 12900)))
    assert r.flags == TickFlag.BAD_SAMPLE and not r.lock_left
    assert r.count_left_cam == 1 << 70 and r.count_left_output == 3100
    assert ctl.tick_index == 2


def test_the_umc_needs_its_models_and_the_kernel_a_compiled_decision() -> None:
    with pytest.raises(ValueError, match="needs 'models'"):
        make_controller("umc")
    with pytest.raises(TypeError, match="Compiled entry points"):
        Kernel(ControllerConfig(), pec.decide, 1)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"Compiled.step must be compiled with numba"):
        Compiled(lambda *a: None, pec.COMPILED.batch)
    with pytest.raises(ValueError, match="divider"):
        Kernel(ControllerConfig(), pec.COMPILED, 0)


def test_reset_forgets_everything_a_run_left_behind(
    squats: AngleRecording, default_sets: tuple[Path, Path]
) -> None:
    ctl = make_controller("umc", _cfg(default_sets, umc_rate_hz=100))
    first = replay_columns(squats, ctl)
    carried = replay_columns(squats, ctl)  # filter, window and holds continue
    ctl.reset()
    again = replay_columns(squats, ctl)
    for name in ("omega_left", "post_squat", "lock_left", "action"):
        np.testing.assert_array_equal(again[name], first[name], err_msg=name)
    assert not np.array_equal(carried["omega_left"][:5], first["omega_left"][:5])
    assert first["omega_left"][0] == 0.0  # a fresh filter starts at rest


def test_eumc_runs_the_umc_at_the_rising_edge_then_every_tenth_triggered_tick(
    squats: AngleRecording, default_sets: tuple[Path, Path]
) -> None:
    cols = replay_columns(squats, make_controller(
        "eumc", _cfg(default_sets, calibration=[0.0, 0.0])))
    trig = cols["trigger"]
    evaluated = np.isfinite(cols["post_squat"])
    assert evaluated.sum() > 20
    since = -1
    for k in range(trig.size):
        since = since + 1 if trig[k] else -1
        assert evaluated[k] == (trig[k] and since % 10 == 0 and k >= 29), k
    # Idle ticks decide "no lock" at 100 Hz without evaluating.
    assert np.all(cols["controller_ran"][~trig]) and np.all(cols["action"][~trig] == 1)
    assert np.all(cols["flags"] & TickFlag.NOT_CALIBRATED == 0)


def test_the_python_building_blocks_show_the_compiled_state(
    squats: AngleRecording, default_sets: tuple[Path, Path]
) -> None:
    """Window, filter and hold objects own the arrays the tick updates."""
    ctl = make_controller("pec")
    cols = replay_columns(squats, ctl)
    window = ctl.kernel.window.view()  # type: ignore[attr-defined]
    np.testing.assert_array_equal(window[:, 0], cols["q_left"][-30:])
    np.testing.assert_array_equal(window[:, 1], cols["q_right"][-30:])
    assert ctl.tick_index == squats.t.size  # type: ignore[attr-defined]
    assert ctl.kernel.velocity.initialised  # type: ignore[attr-defined]
    last_trigger = int(np.flatnonzero(cols["trigger"])[-1])
    expected = max(0, 30 - (squats.t.size - last_trigger))
    assert ctl.kernel.hold.remaining == (expected, expected)  # type: ignore[attr-defined]
