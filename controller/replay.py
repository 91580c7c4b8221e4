"""Offline replay: recorded hip angles through a controller, with the live loop's code.

    exostudy replay --angles IN.csv --controller {umc,eumc,pec,none} \
        [--models MODELS.json] [--utilities UTILITIES.json] [--rate HZ] \
        [--settings SETTINGS.json] [--calibrate-seconds S] --out TICKS.csv

IN.csv has the columns `t,theta_left,theta_right` (seconds, radians) and optionally
`activity,lift_index` (as written by `exostudy simulate`), which are carried into the
ticks as ground truth. TICKS.csv has one row per tick with every `TickRecord` field.

E-UMC needs a calibration: `--calibrate-seconds S` (default 2) takes the first S seconds
of the recording as the standing-still period, exactly as the live calibration does.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.base import Controller
from controller.calibration import calibrate
from controller.config import ControllerConfig
from controller.device.replay import ReplayDevice
from controller.factory import NEEDS_MODELS, controller_names, load_models, make_controller
from controller.loop import ControlLoop
from controller.tick import TickRecord
from controller.tick_csv import write_ticks_csv

REQUIRED_COLUMNS = ("t", "theta_left", "theta_right")


@dataclass(frozen=True)
class AngleRecording:
    """Hip angles from a CSV file, with ground truth if the file carries it."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    activity: list[str] | None
    lift_index: NDArray[np.int64] | None


def read_angles_csv(path: Path) -> AngleRecording:
    """Read and validate an angle file; errors name the row and column."""
    if not path.is_file():
        raise FileNotFoundError(f"no such angle file: {path}")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = reader.fieldnames or []
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}: missing column(s) {', '.join(missing)}; "
                             f"expected {','.join(REQUIRED_COLUMNS)}")
        has_truth = "activity" in header
        t: list[float] = []
        q: list[tuple[float, float]] = []
        act: list[str] = []
        lift: list[int] = []
        for row_no, row in enumerate(reader, start=2):
            vals = []
            for col in REQUIRED_COLUMNS:
                raw = (row.get(col) or "").strip()
                try:
                    v = float(raw)
                except ValueError:
                    raise ValueError(f"{path}: row {row_no}, column {col}: "
                                     f"not a number: {raw!r}") from None
                if col == "t" and not math.isfinite(v):
                    raise ValueError(f"{path}: row {row_no}, column t: not finite")
                if col != "t" and math.isfinite(v) and abs(v) > 2 * math.pi:
                    raise ValueError(f"{path}: row {row_no}, column {col}: {v} rad is not a "
                                     "hip angle (degrees given instead of radians?)")
                vals.append(v)
            if t and vals[0] <= t[-1]:
                raise ValueError(f"{path}: row {row_no}, column t: time {vals[0]} does not "
                                 f"increase (previous {t[-1]})")
            t.append(vals[0])
            q.append((vals[1], vals[2]))
            if has_truth:
                act.append((row.get("activity") or "").strip())
                li = (row.get("lift_index") or "-1").strip()
                try:
                    lift.append(int(li))
                except ValueError:
                    raise ValueError(f"{path}: row {row_no}, column lift_index: "
                                     f"not an integer: {li!r}") from None
    if not t:
        raise ValueError(f"{path}: no data rows")
    return AngleRecording(
        np.asarray(t), np.asarray(q), act if has_truth else None,
        np.asarray(lift, dtype=np.int64) if has_truth else None,
    )


def replay(
    rec: AngleRecording, controller: Controller, precompression_pct: float = 25.0
) -> list[TickRecord]:
    """Run `controller` over the recording through `ControlLoop`, as live."""
    device = ReplayDevice(rec.t, rec.q, precompression_pct, activity=rec.activity,
                          lift_index=rec.lift_index)
    device.open()
    controller.warm_up()
    loop = ControlLoop(device, controller)
    out: list[TickRecord] = []
    while not device.finished:
        r = loop.tick(timeout=0.0)
        if r is not None:
            out.append(r)
    device.close()
    return out


def build(
    name: str,
    models: Path | None,
    utilities: Path | None,
    settings: ControllerConfig,
    rec: AngleRecording,
    calibrate_seconds: float = 2.0,
) -> Controller:
    """The controller for a replay, calibrated from the recording's start for E-UMC."""
    if name not in controller_names():
        raise ValueError(f"unknown controller {name!r}; choose one of {controller_names()}")
    cfg: dict[str, Any] = {}
    if name in NEEDS_MODELS:
        if models is None or utilities is None:
            raise ValueError(f"controller {name} needs --models and --utilities")
        cfg = {"models_path": str(models), "utilities_path": str(utilities)}
    if name == "eumc" and settings.calibration is None:
        mset = load_models(cfg)
        start = np.mean([m.mean[0] for m in mset.ordered()], axis=0)
        n = int(round(calibrate_seconds * 100))
        cal = calibrate(rec.q[:n], start)
        settings = settings.with_calibration(cal.offset_left, cal.offset_right)
    cfg["settings"] = settings
    return make_controller(name, cfg)


def main(argv: Sequence[str] | None = None) -> int:
    """`exostudy replay`."""
    p = argparse.ArgumentParser(prog="exostudy replay", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--angles", required=True, type=Path)
    p.add_argument("--controller", required=True, choices=controller_names())
    p.add_argument("--models", type=Path)
    p.add_argument("--utilities", type=Path)
    p.add_argument("--rate", type=float, help="run every controller at this rate (Hz)")
    p.add_argument("--settings", type=Path, help="JSON file of ControllerConfig fields")
    p.add_argument("--calibrate-seconds", type=float, default=2.0)
    p.add_argument("--out", required=True, type=Path)
    a = p.parse_args(argv)
    try:
        settings = ControllerConfig()
        if a.settings is not None:
            settings = ControllerConfig.from_json(json.loads(a.settings.read_text()))
        if a.rate is not None:
            settings = settings.at_rate(a.rate)
        rec = read_angles_csv(a.angles)
        ctl = build(a.controller, a.models, a.utilities, settings, rec, a.calibrate_seconds)
        ticks = replay(rec, ctl, settings.precompression_pct)
    except (ValueError, FileNotFoundError) as exc:
        print(f"exostudy replay: error: {exc}", file=sys.stderr)
        return 2
    with a.out.open("w", newline="") as f:
        n = write_ticks_csv(ticks, f)
    locks = sum(1 for r in ticks if r.lock_left or r.lock_right)
    print(f"replayed {n} ticks through {a.controller}; {locks} ticks with a lock command; "
          f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
