"""Offline replay: CSV in, ticks out, through the same loop and controllers as live."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from controller.factory import make_controller
from controller.replay import main, read_angles_csv, replay
from controller.sim.recording import simulate_to_csv


@pytest.fixture(scope="module")
def squats(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("angles") / "squats.csv"
    simulate_to_csv(5, "squat-sequence", out)
    return out


def test_cli_writes_one_row_per_tick_with_the_required_columns(
    squats: Path, default_sets: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
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
