"""Offline replay: CSV in, ticks out, through the same loop and controllers as live."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from controller.controllers.factory import load_models, make_controller
from controller.intent.calibration import calibrate
from controller.runner.replay import (
    AngleRecording,
    main,
    read_angles_csv,
    replay,
    replay_columns,
    replay_per_tick,
)
from controller.sim.recording import simulate_to_csv
from controller.tick_codec import (
    columns_from_records,
    records_from_columns,
    write_csv,
    write_records_csv,
)
from controller.tick_record import TickFlag, TickRecord


@pytest.fixture(scope="module")
def squats(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("angles") / "squats.csv"
    simulate_to_csv(5, "squat-sequence", out)
    return out


def test_cli_writes_one_row_per_tick_with_the_required_columns(
    squats: Path,
    default_sets: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    models, folder = default_sets
    out = tmp_path / "ticks.csv"
    code = main(["--angles", str(squats), "--controller", "eumc", "--models", str(models),
                 "--utilities", str(folder / "utilities-sim-p25.json"), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    rows = list(csv.DictReader(out.open()))
    n_in = sum(1 for _ in squats.open()) - 1
    assert len(rows) == n_in
    for col in ("t", "action", "lock_left", "lock_right", "post_squat", "post_stoop_left",
                "post_stoop_right", "post_other"):
        assert col in rows[0]
    assert any(r["lock_left"] == "1" and r["lock_right"] == "1" for r in rows)
    assert {r["truth_activity"] for r in rows} >= {"stand", "squat"}


def test_replay_equals_the_live_controller_on_the_same_samples(squats: Path) -> None:
    rec = read_angles_csv(squats)
    a = replay(rec, make_controller("pec"))
    b = replay(rec, make_controller("pec"))
    strip = ("t_host", "compute_us")
    assert [{k: v for k, v in r.as_dict().items() if k not in strip} for r in a] == [
        {k: v for k, v in r.as_dict().items() if k not in strip} for r in b
    ]
    assert any(r.lock_left for r in a)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("time,theta_left,theta_right\n0,0,0\n", "missing column.*t"),
        ("t,theta_left,theta_right\n0,0,0\n0.01,abc,0\n", "row 3, column theta_left"),
        ("t,theta_left,theta_right\n0,0,0\n0,0,0\n", "row 3, column t: time 0.0 does not"),
        ("t,theta_left,theta_right\n0,45,0\n", "row 2, column theta_left.*degrees"),
        ("t,theta_left,theta_right\n", "no data rows"),
    ],
)
def test_malformed_angle_files_name_the_row_and_column(
    tmp_path: Path, content: str, message: str
) -> None:
    f = tmp_path / "in.csv"
    f.write_text(content)
    with pytest.raises(ValueError, match=message):
        read_angles_csv(f)


def test_cli_reports_errors_without_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "in.csv"
    f.write_text("t,theta_left,theta_right\n0,0,0\n")
    assert main(["--angles", str(f), "--controller", "umc", "--out", str(tmp_path / "o")]) == 2
    assert "needs --models and --utilities" in capsys.readouterr().err


# --------------------------------------------------------------------------- batch path

_TIMING = ("t_host", "compute_us")


def _with_gap(path: Path) -> AngleRecording:
    """The squat recording with a 5-sample gap (NaN) in the left hip, mid-run."""
    rec = read_angles_csv(path)
    q = rec.q.copy()
    q[1500:1505, 0] = np.nan
    return AngleRecording(rec.t, q, rec.activity, rec.lift_index)


def _calibration(models: Path, rec: AngleRecording) -> list[float]:
    mset = load_models({"models_path": str(models)})
    cal = calibrate(rec.q[:200], mset.start_posture())
    return [cal.offset_left, cal.offset_right]


@pytest.mark.parametrize(
    ("name", "settings"),
    [
        ("umc", {"umc_rate_hz": 100}),
        ("umc", {"band": 20}),
        ("eumc", "calibrated"),
        ("eumc", {}),
        ("pec", {}),
        ("pec", {"pec_rate_hz": 20, "hold_s": 0.1}),
    ],
)
def test_batch_replay_equals_the_per_tick_live_path(
    squats: Path, default_sets: tuple[Path, Path], name: str, settings: dict[str, Any] | str
) -> None:
    """Same recording, same controller: the compiled batch loop and `ControlLoop` over
    `ReplayDevice` (one `step` per tick) give the same ticks, column for column, and
    leave the controller in the same state. Only wall-clock timing may differ."""
    models, folder = default_sets
    rec = _with_gap(squats)
    if settings == "calibrated":
        settings = {"calibration": _calibration(models, rec)}
    cfg = {"models_path": str(models), "utilities_path": str(folder / "utilities-sim-p25.json"),
           "settings": settings}
    batch_ctl, live_ctl = make_controller(name, cfg), make_controller(name, cfg)
    batch = replay_columns(rec, batch_ctl)
    live = columns_from_records(replay_per_tick(rec, live_ctl, clock=lambda: 0.0))
    assert list(batch) == list(TickRecord.field_names())
    for col in TickRecord.field_names():
        if col in _TIMING:
            continue
        assert batch[col].dtype == live[col].dtype, col
        np.testing.assert_array_equal(batch[col], live[col], err_msg=col)
    for a, b in zip(batch_ctl.kernel.arrays(), live_ctl.kernel.arrays(), strict=True):  # type: ignore[attr-defined]
        np.testing.assert_array_equal(a, b)
    # The comparison had something to compare: locks, a bad sample, the mechanism.
    assert batch["flags"][1500] & TickFlag.BAD_SAMPLE
    if name == "eumc" and settings == {}:
        assert np.all(batch["flags"] & TickFlag.NOT_CALIBRATED | batch["flags"] & 1)
        assert not batch["lock_left"].any()
    else:
        assert batch["lock_left"].sum() > 100 and batch["locked_left"].sum() > 100
        assert np.nanmax(batch["torque_left"]) > 5.0
    if name == "umc":
        assert np.isfinite(batch["post_squat"]).sum() > 500
    if name == "eumc" and settings != {}:
        assert 20 < np.isfinite(batch["post_squat"]).sum() < batch["trigger"].sum()


def test_batch_replay_feeds_the_lock_command_back_into_the_mechanism(squats: Path) -> None:
    """With the PEC's locks the springs load (deflection, torque); without any lock the
    same recording leaves them slack: the replayed mechanism obeys the commands."""
    rec = read_angles_csv(squats)
    pec = replay_columns(rec, make_controller("pec"))
    free = replay_columns(rec, make_controller("none"))
    assert np.nanmax(pec["alpha_left"]) > 0.3 and pec["torque_left"].max() > 10.0
    assert np.nanmax(np.abs(free["alpha_left"])) < 1e-3 and not free["locked_left"].any()
    # A lock command reaches the mechanism one tick later, as on the device.
    first_lock = int(np.argmax(pec["lock_left"]))
    assert not pec["locked_left"][: first_lock + 1].any()


def test_columns_records_and_csv_agree(squats: Path) -> None:
    rec = read_angles_csv(squats)
    cols = replay_columns(rec, make_controller("pec"))
    records = records_from_columns(cols)
    assert len(records) == cols["t"].size
    assert records[100].t == cols["t"][100] and records[100].lock_left == cols["lock_left"][100]
    back = columns_from_records(records)
    for name in TickRecord.field_names():
        np.testing.assert_array_equal(back[name], cols[name], err_msg=name)
    a, b = io.StringIO(), io.StringIO()
    assert write_csv(cols, a) == write_records_csv(records, b) == len(records)
    assert a.getvalue() == b.getvalue()
    assert ",," in a.getvalue()  # NaN is an empty cell
