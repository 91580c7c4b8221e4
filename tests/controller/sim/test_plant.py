"""The hip module (ratchet, pawl, springs, hard stop) and the encoders."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.device.base import Status
from controller.lowlevel.actuator import maccepa_torque, max_deflection
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.plant import CAM, OUTPUT, EncoderModel, ExoPlant, HipModule

D = math.radians
PITCH = D(9.0)


def ramp(a: float, b: float, n: int = 100) -> np.ndarray:
    return np.linspace(D(a), D(b), n)


def drive(hip: HipModule, angles: np.ndarray, solenoid: bool = True) -> list[float]:
    torques = []
    for a in angles:
        hip.step(solenoid, float(a))
        torques.append(hip.torque())
    return torques


def test_unlocked_cam_follows_output() -> None:
    hip = HipModule(25.0)
    hip.reset(0.0)
    torques = drive(hip, ramp(0, 80), solenoid=False)
    assert not hip.locked and hip.alpha == 0.0 and max(torques) == 0.0
    assert hip.cam == hip.output == pytest.approx(D(80))


def test_lock_command_during_extension_gives_no_torque() -> None:
    hip = HipModule(25.0, tooth_phase=D(2.0))
    hip.reset(D(80))
    torques = drive(hip, ramp(80, 0), solenoid=True)
    assert max(torques) == 0.0
    assert not hip.locked and hip.alpha == 0.0
    assert hip.cam == pytest.approx(0.0)


def test_lock_during_flexion_gives_the_maccepa_torque_of_the_quantised_deflection() -> None:
    phase = D(3.0)
    hip = HipModule(25.0, tooth_phase=phase)
    hip.reset(D(10.0))
    hip.step(True, D(10.0))  # pull-in: first tick
    hip.step(True, D(10.0))  # pawl on the ratchet
    assert not hip.locked
    drive(hip, ramp(10, 50))
    assert hip.locked
    tooth = phase + PITCH * math.ceil((D(10.0) - phase) / PITCH)  # 12 deg
    assert hip.cam == pytest.approx(tooth)
    assert 0.0 <= hip.cam - D(10.0) < PITCH  # grounded at the next tooth
    assert hip.alpha == pytest.approx(D(50.0) - tooth)
    assert hip.torque() == pytest.approx(maccepa_torque(D(50.0) - tooth, 25.0))
    assert 7.0 < hip.torque() < 11.0  # 38 deg at 25 %: between T(30) and T(60)


def test_engagement_is_at_the_next_tooth_after_the_lowest_point() -> None:
    hip = HipModule(25.0, tooth_phase=0.0)
    hip.reset(D(40.0))
    down_up = np.concatenate([ramp(40, 13.5, 50), ramp(13.5, 60, 80)])
    drive(hip, down_up)
    assert hip.locked
    assert hip.cam == pytest.approx(D(18.0))  # first tooth above 13.5 deg


def test_release_at_zero_deflection_and_relock_only_when_commanded() -> None:
    hip = HipModule(25.0, tooth_phase=0.0)
    hip.reset(0.0)
    drive(hip, ramp(0.5, 60))
    assert hip.locked and hip.cam == pytest.approx(D(9.0))
    # Extension back past the lock point releases the pawl, even with the solenoid off.
    torques = drive(hip, ramp(60, 0), solenoid=False)
    assert not hip.locked and hip.alpha == 0.0 and torques[-1] == 0.0
    assert hip.output == pytest.approx(0.0)
    # Monotonic torque while extending: it falls with the deflection.
    locked_part = [t for t in torques if t > 0]
    assert all(a >= b for a, b in itertools.pairwise(locked_part))
    drive(hip, ramp(0, 60), solenoid=False)
    assert not hip.locked and hip.torque() == 0.0


def test_a_one_tick_pulse_does_not_seat_the_pawl() -> None:
    hip = HipModule(25.0)
    hip.reset(0.0)
    angles = ramp(0, 60)
    hip.step(True, float(angles[0]))
    drive(hip, angles[1:], solenoid=False)
    assert not hip.locked


def test_hard_stop_at_the_22_mm_compression_limit() -> None:
    hip = HipModule(25.0, tooth_phase=0.0)
    hip.reset(0.0)
    drive(hip, ramp(0.5, 120))
    limit = max_deflection(25.0)
    assert math.degrees(limit) == pytest.approx(78.0, abs=0.2)
    assert hip.hard_stop
    assert hip.output == pytest.approx(hip.cam + limit)
    assert hip.torque() == pytest.approx(maccepa_torque(limit, 25.0))
    drive(hip, ramp(120, 60))
    assert not hip.hard_stop and hip.output == pytest.approx(D(60))


def test_plant_status_bits_and_torques() -> None:
    plant = ExoPlant(50.0)
    plant.reset(0.0, 0.0)
    status = Status.NONE
    for a in ramp(0, 90):
        status = plant.step(True, False, float(a), float(a))
    assert status & Status.SOLENOID_LEFT and not status & Status.SOLENOID_RIGHT
    assert status & Status.LOCKED_LEFT and not status & Status.LOCKED_RIGHT
    assert status & Status.HARD_STOP_LEFT and not status & Status.HARD_STOP_RIGHT
    left, right = plant.torques()
    assert left > 20.0 and right == 0.0


def test_counts_round_trip_through_the_layout_within_the_noise() -> None:
    rng = np.random.default_rng(0)
    plant = ExoPlant(25.0, DEFAULT_LAYOUT, EncoderModel.ideal())
    for a in rng.uniform(-0.5, 2.0, 200):
        plant.reset(float(a), float(-a / 2))
        th_l, al_l, th_r, _al_r = DEFAULT_LAYOUT.joint_angles(plant.counts((0.0,) * 4))
        assert th_l == pytest.approx(a, abs=D(0.0111))
        assert th_r == pytest.approx(-a / 2, abs=D(0.0111))
        assert al_l == pytest.approx(0.0, abs=D(0.0221))

    enc = EncoderModel.from_seed()
    plant = ExoPlant(25.0, DEFAULT_LAYOUT, enc)
    errors, nonlin = [], []
    for a in rng.uniform(-0.5, 2.0, 3000):
        plant.reset(float(a), float(a))
        noise = tuple(float(x) for x in rng.standard_normal(4))
        got = DEFAULT_LAYOUT.joint_angles(plant.counts(noise))
        nl = enc.error(0, float(a))
        errors.append(got[0] - a - nl)
        nonlin.append(nl)
    err = np.degrees(np.array(errors))
    assert np.sqrt(np.mean(err**2)) <= 0.06  # AS5048A noise spec
    assert np.sqrt(np.mean(err**2)) > 0.02  # but there is noise
    nl_deg = np.degrees(np.abs(nonlin))
    assert nl_deg.max() <= 0.8 and nl_deg.max() > 0.1


def _random_drive(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Thigh angles that flex and extend across many teeth, up to past the hard stop,
    and solenoid commands in blocks of 1..40 ticks (one-tick pulses included)."""
    t = np.arange(n) * 0.01
    angles = np.zeros(n)
    for _ in range(4):
        amp, freq, phase = rng.uniform(0.1, 0.8), rng.uniform(0.1, 1.5), rng.uniform(0, 6.3)
        angles += amp * np.sin(2 * np.pi * freq * t + phase)
    angles += rng.normal(0.0, D(0.3), n)  # small reversals inside every swing
    commands = np.zeros(n, dtype=bool)
    k = 0
    while k < n:
        length = int(rng.integers(1, 41))
        commands[k : k + length] = rng.random() < 0.5
        k += length
    return angles, commands


@pytest.mark.parametrize("precompression", [0.0, 25.0, 60.0, 100.0])
def test_mechanism_equals_the_reference_python_model_tick_for_tick(
    precompression: float,
) -> None:
    """The mechanism must behave exactly as the reviewed Python model (kept as the
    oracle in `reference_plant.py`): same links, lock, hard stop and torque, bit for bit."""
    from tests.controller.sim.reference_plant import ReferenceHipModule

    rng = np.random.default_rng(int(precompression) + 7)
    for trial in range(6):
        phase = float(rng.uniform(0.0, PITCH))
        angles, commands = _random_drive(rng, 3000)
        hip = HipModule(precompression, tooth_phase=phase)
        ref = ReferenceHipModule(precompression, tooth_phase=phase)
        hip.reset(float(angles[0]))
        ref.reset(float(angles[0]))
        locks = hard = 0
        for k in range(angles.size):
            hip.step(bool(commands[k]), float(angles[k]))
            ref.step(bool(commands[k]), float(angles[k]))
            got = (hip.output, hip.cam, hip.locked, hip.hard_stop, hip.solenoid, hip.torque())
            want = (ref.output, ref.cam, ref.locked, ref.hard_stop, ref.solenoid, ref.torque())
            assert got == want, (trial, k)
            locks += ref.locked
            hard += ref.hard_stop
        assert locks > 100  # the sequence really exercised the ratchet
        if precompression < 100.0 and trial == 0:
            assert hard > 0 or precompression == 0.0


def test_plant_status_equals_the_reference_models_on_both_sides() -> None:
    from tests.controller.sim.reference_plant import ReferenceHipModule

    rng = np.random.default_rng(3)
    plant = ExoPlant(25.0)
    refs = [ReferenceHipModule(25.0, tooth_phase=h.tooth_phase) for h in (plant.left, plant.right)]
    (al, cl), (ar, cr) = _random_drive(rng, 4000), _random_drive(rng, 4000)
    plant.reset(float(al[0]), float(ar[0]))
    refs[0].reset(float(al[0]))
    refs[1].reset(float(ar[0]))
    seen = Status.NONE
    for k in range(al.size):
        status = plant.step(bool(cl[k]), bool(cr[k]), float(al[k]), float(ar[k]))
        refs[0].step(bool(cl[k]), float(al[k]))
        refs[1].step(bool(cr[k]), float(ar[k]))
        want = Status.NONE
        for ref, sol, lk, hs, cmd in (
            (refs[0], Status.SOLENOID_LEFT, Status.LOCKED_LEFT, Status.HARD_STOP_LEFT, cl[k]),
            (refs[1], Status.SOLENOID_RIGHT, Status.LOCKED_RIGHT, Status.HARD_STOP_RIGHT, cr[k]),
        ):
            want |= (sol if cmd else Status.NONE) | (lk if ref.locked else Status.NONE)
            want |= hs if ref.hard_stop else Status.NONE
        assert status == want, k
        assert plant.link_angles() == (refs[0].output, refs[0].cam, refs[1].output, refs[1].cam)
        assert plant.torques() == (refs[0].torque(), refs[1].torque())
        seen |= status
    assert seen & Status.LOCKED_LEFT and seen & Status.LOCKED_RIGHT
    assert seen & Status.HARD_STOP_LEFT and seen & Status.HARD_STOP_RIGHT


def _reference_counts(plant: ExoPlant, noise: tuple[float, float, float, float]
                      ) -> tuple[int, int, int, int]:
    """`ExoPlant.counts` as it was in Python: angle + non-linearity + noise, encoded."""
    enc = plant.encoders
    a = plant.link_angles()
    m = [a[i] + enc.error(i, a[i]) + enc.noise_rad * noise[i] for i in range(4)]
    return plant.layout.encode(m[0], m[1], m[2], m[3])


@given(
    st.lists(st.floats(-7.0, 7.0), min_size=4, max_size=4),
    st.lists(st.floats(-6.0, 6.0), min_size=4, max_size=4),
    st.sampled_from([EncoderModel.from_seed(), EncoderModel.from_seed(11),
                     EncoderModel.ideal()]),
    st.sampled_from([DEFAULT_LAYOUT, EncoderLayout((0, 16383, 5, 8191), (-1, 1, 1, -1))]),
)
def test_compiled_counts_equal_the_python_encoder_model(
    angles: list[float], noise: list[float], enc: EncoderModel, layout: EncoderLayout
) -> None:
    plant = ExoPlant(25.0, layout, enc)
    plant.state[0, OUTPUT], plant.state[0, CAM], plant.state[1, OUTPUT], plant.state[1, CAM] = (
        angles)
    drawn = (noise[0], noise[1], noise[2], noise[3])
    assert plant.counts(drawn) == _reference_counts(plant, drawn)


def test_status_is_the_flag_of_the_bits_the_compiled_step_returns() -> None:
    plant = ExoPlant(25.0)
    plant.reset(0.0, 0.0)
    seen = set()
    for k, a in enumerate(np.concatenate([ramp(0, 100, 300), ramp(100, 0, 300)] * 3)):
        lock = (k // 40) % 3 != 0
        status = plant.step(lock, (k // 70) % 2 == 0, float(a), float(a) * 0.9)
        assert type(status) is Status
        bits = int(status)
        assert status == Status(bits)
        seen.add(bits)
    assert len(seen) > 4
