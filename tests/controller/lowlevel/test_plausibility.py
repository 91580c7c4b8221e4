"""Plausible samples only: what a hip cannot do is flagged before any controller sees it,
and never leads to a new lock (live path, `KernelController.step`)."""

from __future__ import annotations

import math
import random
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.controllers.factory import load_models, make_controller
from controller.controllers.pec import PEC
from controller.device.base import LockCommand, Sample
from controller.intent.calibration import calibrate
from controller.lowlevel.encoders import DEFAULT_LAYOUT
from controller.lowlevel.plausibility import HIP_ACCELERATION_MAX, HIP_VELOCITY_MAX, course_bound
from controller.runner.loop import ControlLoop
from controller.sim.scripts import SCRIPT_NAMES
from controller.sim.simulated_device import SimulatedDevice
from controller.tick_record import Plausibility, TickFlag, TickRecord


def _sample(k: int, q_left: float, q_right: float, t: float | None = None) -> Sample:
    """Hips at the given flexion, springs undeflected, at tick k (t = k * 10 ms)."""
    counts = DEFAULT_LAYOUT.encode(q_left, q_left, q_right, q_right)
    return Sample(seq=k, t=k * 0.01 if t is None else t, counts=counts)


def _stand(ctl: PEC, ticks: int, q: float = 0.1) -> list[TickRecord]:
    return [ctl.step(_sample(k, q, q)) for k in range(ticks)]


def _locks(records: list[TickRecord]) -> int:
    return sum(r.lock_left or r.lock_right for r in records)


@pytest.mark.parametrize("script", SCRIPT_NAMES)
def test_every_simulated_human_movement_is_plausible(script: str) -> None:
    """The wearer's own movements (lifts, walking, stairs), through the simulated
    exoskeleton and encoders with their noise, never trip a bound."""
    dev = SimulatedDevice(seed=3, script=script, realtime=False, loop=False)
    dev.open()
    loop = ControlLoop(dev, make_controller("pec"))
    flagged = total = 0
    while total < 3000 and not dev.exo.finished:
        r = loop.tick(0.0)
        if r is not None:
            total += 1
            flagged += r.plausibility != 0
    assert total > 1000
    assert flagged == 0


glitches = st.floats(course_bound(0.01) * 1.01, 2.5) | st.floats(-2.5, -course_bound(0.01) * 1.01)


@settings(max_examples=60, deadline=None)
@given(glitches, st.integers(40, 80), st.booleans())
def test_a_single_sample_glitch_never_locks(jump: float, at: int, both: bool) -> None:
    """A still wearer, one sample of both (or one) hips elsewhere by more than a hip can
    move in 10 ms: with the PEC, a glitch on both hips used to be a lock (a velocity
    spike). Smaller glitches look like, and are treated as, motion."""
    ctl = PEC()
    out = []
    for k in range(120):
        q = 0.1 + (jump if k == at else 0.0)
        out.append(ctl.step(_sample(k, q, q if both else 0.1)))
    assert _locks(out) == 0
    glitch = out[at]
    assert glitch.flags & TickFlag.IMPLAUSIBLE or glitch.flags & TickFlag.BAD_SAMPLE
    assert out[at + 1].plausibility == 0  # the next good sample is compared with a good one
    assert max(abs(r.omega_left) for r in out[at + 1 :]) < 0.1


def test_228_rad_per_s_is_flagged_not_used() -> None:
    ctl = PEC()
    out = _stand(ctl, 50)
    k = 50
    out.append(ctl.step(_sample(k, 0.1 + 2.28, 0.1 + 2.28)))  # 228 rad/s for 10 ms
    assert out[-1].plausibility & Plausibility.RANGE or out[-1].plausibility & Plausibility.JUMP
    ctl2 = PEC()
    _stand(ctl2, 50)
    r = ctl2.step(_sample(50, 0.1 + 0.5, 0.1 + 0.5))  # 50 rad/s: inside the range, a jump
    assert r.plausibility == Plausibility.JUMP and r.flags == TickFlag.IMPLAUSIBLE
    assert math.isnan(r.omega_left) and not r.lock_left
    assert _locks(out) == 0


def test_fastest_human_hip_passes() -> None:
    """Accelerating at 90 % of the bound up to 90 % of the velocity bound: plausible
    all the way, the filter follows, and the PEC triggers."""
    ctl = PEC()
    _stand(ctl, 30, 0.0)
    a, v_top = 0.9 * HIP_ACCELERATION_MAX, 0.9 * HIP_VELOCITY_MAX
    out, q, v = [], 0.0, 0.0
    for k in range(1, 12):
        v = min(v + a * 0.01, v_top)
        q += v * 0.01
        out.append(ctl.step(_sample(30 + k, q, q)))
    assert all(r.plausibility == 0 for r in out)
    assert out[-1].omega_left == pytest.approx(v_top, rel=0.25)
    assert _locks(out) > 0


def test_repeated_early_and_backwards_samples() -> None:
    ctl = PEC()
    _stand(ctl, 20)
    again = ctl.step(_sample(19, 0.1, 0.1))  # the last sample once more
    assert again.plausibility == Plausibility.REPEATED and again.flags == TickFlag.IMPLAUSIBLE
    early = ctl.step(_sample(20, 0.1, 0.1, t=0.193))  # 3 ms after the last one
    assert early.plausibility == Plausibility.TOO_EARLY
    ok = ctl.step(_sample(21, 0.1, 0.1, t=0.20))
    assert ok.plausibility == 0
    back = ctl.step(_sample(22, 0.1, 0.1, t=0.05))  # device restarted
    assert back.plausibility == Plausibility.TIME_BACKWARDS
    after = ctl.step(_sample(23, 0.1, 0.1, t=0.06))
    assert after.plausibility == 0 and after.omega_left == 0.0  # the filter restarted


def test_after_a_silence_the_filters_restart() -> None:
    ctl = PEC()
    _stand(ctl, 20, 0.1)
    r = ctl.step(_sample(40, 0.6, 0.6))  # 0.19 s later, somewhere else: plausible motion
    assert r.plausibility == Plausibility.RESYNC
    nxt = ctl.step(_sample(41, 0.6, 0.6))
    assert nxt.plausibility == 0 and abs(nxt.omega_left) < 0.5 and not nxt.lock_left


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 8), st.floats(0.3, 3.0))
def test_lost_samples_do_not_read_as_a_faster_hip(missing: int, v: float) -> None:
    """Constant-velocity flexion with `missing` samples lost: the filter's velocity
    after the gap stays near the true one (the fixed 10 ms step used to read a 30 ms
    step as three times the speed)."""
    ctl = PEC()
    k = 0
    for k in range(40):
        ctl.step(_sample(k, v * 0.01 * k, v * 0.01 * k))
    k += 1 + missing
    r = ctl.step(_sample(k, v * 0.01 * k, v * 0.01 * k))
    assert r.plausibility == 0
    assert r.omega_left == pytest.approx(v, abs=0.25 * v + 0.05)


def _run_stream(script: str, controller: str, cfg: dict[str, object], glitch_rate: float,
                ticks: int) -> list[TickRecord]:
    """A simulated wearer through `controller`, one random count on a random encoder in
    `glitch_rate` of the samples (seeded: the same glitches every run)."""
    rng = random.Random(11)
    dev = SimulatedDevice(seed=2, script=script, realtime=False, loop=False)
    dev.open()
    ctl = make_controller(controller, cfg)
    out = []
    while not dev.exo.finished and len(out) < ticks:
        s = dev.read(0.0)
        if s is None:
            continue
        if rng.random() < glitch_rate:
            c = list(s.counts)
            c[rng.randrange(4)] = rng.randrange(16384)
            s = replace(s, counts=(c[0], c[1], c[2], c[3]))
        r = ctl.step(s)
        dev.send(LockCommand(r.seq, r.lock_left, r.lock_right))
        out.append(r)
    return out


def _onsets(rs: list[TickRecord]) -> list[int]:
    return [i for i in range(1, len(rs))
            if (rs[i].lock_left and not rs[i - 1].lock_left)
            or (rs[i].lock_right and not rs[i - 1].lock_right)]


def test_five_percent_encoder_glitches_add_no_lock_to_squats() -> None:
    """The issue's case: a squat stream with 5 % single-sample count glitches (a random
    count on a random encoder). PEC lock onsets are those of the clean stream."""
    run = lambda rate: _run_stream("squat-sequence", "pec", {}, rate, 4000)  # noqa: E731
    onsets = _onsets
    clean, glitched = run(0.0), run(0.05)
    assert sum(r.plausibility != 0 for r in glitched) > 100
    assert len(onsets(clean)) >= 3
    # The same locks; one may come a few ticks later when its trigger tick was a glitch.
    assert len(onsets(glitched)) == len(onsets(clean))
    assert all(0 <= g - c <= 5 for g, c in zip(onsets(glitched), onsets(clean), strict=True))
    assert abs(_locks(glitched) - _locks(clean)) <= 0.02 * _locks(clean)


def test_five_percent_glitches_add_no_lock_to_the_eumc(default_sets: tuple[Path, Path]) -> None:
    """The same for the E-UMC (calibrated on the wearer's first two seconds), which the
    issue measured going from 90 to 138 locks with glitches."""
    models, folder = default_sets
    calib = _run_stream("squat-sequence", "none", {}, 0.0, 200)
    q = np.array([[r.q_raw_left, r.q_raw_right] for r in calib])
    mset = load_models({"models_path": str(models)})
    start = mset.start_posture()
    cal = calibrate(q, start)
    cfg = {"models_path": str(models), "utilities_path": str(folder / "utilities-sim-p25.json"),
           "settings": {"calibration": [cal.offset_left, cal.offset_right]}}
    clean = _run_stream("squat-sequence", "eumc", cfg, 0.0, 4000)
    glitched = _run_stream("squat-sequence", "eumc", cfg, 0.05, 4000)
    on_clean, on_glitched = _onsets(clean), _onsets(glitched)
    assert len(on_clean) >= 3
    # The same lifts get locks, none outside a lift, about as long. (Within a lift the
    # E-UMC may lock one side a few ticks before the other where it locked both at once.)
    assert {glitched[i].truth_lift for i in on_glitched} == {clean[i].truth_lift
                                                              for i in on_clean}
    assert all(glitched[i].truth_lift >= 0 for i in on_glitched)
    assert abs(_locks(glitched) - _locks(clean)) <= 0.02 * _locks(clean)


def test_a_held_lock_is_not_carried_over_a_silence_or_a_device_restart() -> None:
    """Both would make the held command a new lock: after 100 ms of silence the device's
    watchdog has let go, and a restarted device starts released."""
    for later in (0.25, 0.05):  # 0.25 s of silence; device time back at 0.05 s
        ctl = PEC()
        _stand(ctl, 50, 0.0)
        k, q, v, out = 49, 0.0, 0.0, []
        while not (out and out[-1].lock_left):  # accelerate until the PEC locks
            k += 1
            v = min(v + 100.0 * 0.01, 3.0)
            q += v * 0.01
            out.append(ctl.step(_sample(k, q, q)))
        assert ctl.kernel.hold.remaining[0] > 0
        r = ctl.step(_sample(k + 1, q, q, t=k * 0.01 + later if later > 0.1 else later))
        assert r.plausibility in (Plausibility.RESYNC, Plausibility.TIME_BACKWARDS)
        assert not r.lock_left and not r.lock_right
        assert ctl.kernel.hold.remaining == (0, 0)


def test_an_encoder_that_jumps_and_stays_is_resynchronised_not_read_as_motion() -> None:
    """Both hips read 0.5 rad more from one sample on (a re-zeroed encoder): flagged
    until the resync time has passed, then taken with the filters restarted, so the
    step never becomes a velocity."""
    ctl = PEC()
    _stand(ctl, 50, 0.1)
    out = [ctl.step(_sample(k, 0.6, 0.6)) for k in range(50, 80)]
    flagged = [r for r in out if r.plausibility]
    assert len(flagged) == 11  # up to 100 ms after the last good sample, then the resync
    assert flagged[-1].plausibility == Plausibility.RESYNC
    assert max(abs(r.omega_left) for r in out if r.omega_left == r.omega_left) < 0.1
    assert _locks(out) == 0

