"""Offline replay: recorded hip angles through a controller, with the live loop's code.

The paper's controllers replay in one compiled loop (`replay_columns`) over the very
tick function the live loop calls, with the exoskeleton's mechanism simulated between
ticks; `replay_per_tick` is the same run through `ControlLoop`, one sample at a time.

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
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from controller.config import ControllerConfig
from controller.controllers import registry
from controller.controllers.factory import (
    controller_names,
    load_models,
    make_from_spec,
    needs_models,
)
from controller.controllers.spec import ControllerSpec
from controller.device.base import SAMPLE_PERIOD_S
from controller.intent.calibration import calibrate
from controller.interface import Controller
from controller.kernel.controller import KernelController
from controller.kernel.records import ROW, ROW_FIELDS
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.runner.loop import ControlLoop
from controller.sim.replay_device import ReplayDevice
from controller.tick_codec import (
    TICK_DTYPE,
    columns_from_records,
    records_from_columns,
    write_csv,
)
from controller.tick_record import TickColumns, TickRecord

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


def replay_columns(
    rec: AngleRecording,
    controller: Controller,
    precompression_pct: float = 25.0,
    layout: EncoderLayout = DEFAULT_LAYOUT,
) -> TickColumns:
    """Run `controller` over the recording; one column per `TickRecord` field.

    For a controller run by the kernel (`KernelController`) this is one compiled loop
    (its `Compiled.batch`, see `controller.kernel.tick`) over its own tick and
    state, with the mechanism of `ReplayDevice` in between: the same code, samples and
    commands as the per-tick path through `ControlLoop`, several times faster
    (`bench/bench_replay.py`: a 10-minute UMC at 100 Hz in about 0.4 s). Tick for tick
    the columns equal that path's records, except for what only a real-time loop has: `t_host` is
    the wall-clock time at which the replay started, `compute_us` the mean compute time
    per tick, and no tick carries the loop's OVERRUN or GAP flags. Other controllers
    (`none`, or any that is not a `KernelController`) take the per-tick path.
    """
    device = ReplayDevice(rec.t, rec.q, precompression_pct, layout, activity=rec.activity,
                          lift_index=rec.lift_index)
    if not isinstance(controller, KernelController):
        return columns_from_records(replay_per_tick(rec, controller, precompression_pct, layout))
    device.open()
    controller.warm_up()
    t = np.ascontiguousarray(device.t, dtype=np.float64)
    q = np.ascontiguousarray(device.q, dtype=np.float64)
    k = t.size
    out = np.empty(k, dtype=ROW)
    counts = np.empty((k, 4), dtype=np.int64)
    status = np.empty(k, dtype=np.int64)
    t_host = time.time()
    t0 = time.perf_counter()
    kern = controller.kernel
    run = cast(Callable[..., None], kern.compiled.batch)
    run(kern.state, kern.data, device.plant.state, device.plant.constants,
        np.array([*layout.offsets, *layout.directions], dtype=np.int64), t, q, out, counts,
        status)
    per_tick_us = (time.perf_counter() - t0) * 1e6 / k
    device.close()
    cols: TickColumns = {
        "seq": np.arange(k, dtype=np.int64),
        "t": t.copy(),
        "t_host": np.full(k, t_host),
        "count_left_output": counts[:, 0].copy(),
        "count_left_cam": counts[:, 1].copy(),
        "count_right_output": counts[:, 2].copy(),
        "count_right_cam": counts[:, 3].copy(),
    }
    types = TickRecord.field_types()
    for name in ROW_FIELDS:
        col = out[name]
        kind = types[name]
        cols[name] = (col.astype(np.int64) if kind is int else col != 0.0 if kind is bool
                      else col.copy())
    cols["compute_us"] = np.full(k, per_tick_us)
    cols["truth_activity"] = np.array(rec.activity if rec.activity is not None else [""] * k,
                                      dtype=TICK_DTYPE["truth_activity"])
    cols["truth_lift"] = (np.asarray(rec.lift_index, dtype=np.int64).copy()
                          if rec.activity is not None and rec.lift_index is not None
                          else np.full(k, -1, dtype=np.int64))
    cols["truth_progress"] = np.full(k, np.nan)
    return {n: cols[n] for n in TickRecord.field_names()}


def replay(
    rec: AngleRecording, controller: Controller, precompression_pct: float = 25.0
) -> list[TickRecord]:
    """`replay_columns` as tick records (convenient for short recordings)."""
    return records_from_columns(replay_columns(rec, controller, precompression_pct))


def replay_per_tick(
    rec: AngleRecording,
    controller: Controller,
    precompression_pct: float = 25.0,
    layout: EncoderLayout = DEFAULT_LAYOUT,
    clock: Callable[[], float] = time.perf_counter,
) -> list[TickRecord]:
    """Run `controller` over the recording through `ControlLoop` and `ReplayDevice`,
    one Python call per tick, exactly as live (the reference for `replay_columns`).

    `clock` is the loop's clock; a constant one keeps OVERRUN flags, which depend on
    how busy the machine is, out of a comparison.
    """
    device = ReplayDevice(rec.t, rec.q, precompression_pct, layout, activity=rec.activity,
                          lift_index=rec.lift_index)
    device.open()
    controller.warm_up()
    loop = ControlLoop(device, controller, clock=clock)
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
    """The controller for a replay; one that needs a calibration (the E-UMC) is
    calibrated from the recording's start, against the model set's start posture."""
    if name not in controller_names():
        raise ValueError(f"unknown controller {name!r}; choose one of {controller_names()}")
    if needs_models(name) and (models is None or utilities is None):
        raise ValueError(f"controller {name} needs --models and --utilities")
    spec = ControllerSpec(name, settings,
                          models_path=None if models is None else str(models),
                          utilities_path=None if utilities is None else str(utilities))
    if registry.needs_calibration(name) and settings.calibration is None:
        if models is None:
            raise ValueError(f"controller {name} calibrates from the recording's start "
                             "against the models' start posture: give --models")
        mset = load_models(spec)
        start = mset.start_posture()
        n = round(calibrate_seconds / SAMPLE_PERIOD_S)
        cal = calibrate(rec.q[:n], start)
        spec = replace(spec, settings=settings.with_calibration(cal.offset_left,
                                                                cal.offset_right))
    return make_from_spec(spec)


def main(argv: Sequence[str] | None = None) -> int:
    """`exostudy replay`."""
    from controller.help_format import DefaultsHelpFormatter

    p = argparse.ArgumentParser(prog="exostudy replay", description=__doc__,
                                formatter_class=DefaultsHelpFormatter)
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
        cols = replay_columns(rec, ctl, settings.precompression_pct)
    except (ValueError, FileNotFoundError) as exc:
        print(f"exostudy replay: error: {exc}", file=sys.stderr)
        return 2
    with a.out.open("w", newline="") as f:
        n = write_csv(cols, f)
    locks = int(np.count_nonzero(cols["lock_left"] | cols["lock_right"]))
    print(f"replayed {n} ticks through {a.controller}; {locks} ticks with a lock command; "
          f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
