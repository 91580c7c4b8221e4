"""The built-in reference human dataset: deterministic, versioned, plausible."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.human_data import HumanMotionData
from controller.sim import human_dataset
from controller.sim.human_dataset import reference_dataset, write_reference_dataset


@pytest.fixture(scope="module")
def data() -> HumanMotionData:
    return reference_dataset(seed=0, participants=8, repetitions=3)


def test_deterministic_and_versioned(data: HumanMotionData) -> None:
    again = reference_dataset(seed=0, participants=8, repetitions=3)
    assert np.array_equal(again.theta, data.theta) and np.array_equal(again.tau, data.tau)
    assert again.version == data.version and data.version.startswith("sim-")
    other = reference_dataset(seed=1, participants=8, repetitions=3)
    assert other.version != data.version
    assert not np.allclose(other.theta, data.theta)
    assert data.meta["participants"] == 8 and data.meta["box_kg"] == 10.0


def test_version_changes_with_the_generator(monkeypatch: pytest.MonkeyPatch) -> None:
    before = human_dataset.generator_version(seed=0)
    monkeypatch.setattr(human_dataset, "GENERATOR_VERSION", "changed")
    assert human_dataset.generator_version(seed=0) != before
    monkeypatch.setattr(human_dataset.inspect, "getsource", lambda obj: "changed")
    # The source is read once per process: a new source is a new process's.
    human_dataset._generator_source.cache_clear()
    try:
        assert human_dataset.generator_version(seed=0) != before
    finally:
        human_dataset._generator_source.cache_clear()


def test_the_version_is_known_without_the_data(data: HumanMotionData) -> None:
    """A cache of derived data (the server's default utilities) is checked against
    `reference_version`, which must name exactly the data `reference_dataset` gives."""
    assert human_dataset.reference_version(0, 8, 3) == data.version
    assert human_dataset.reference_version(0, 8, 3, 5.0) == reference_dataset(
        seed=0, participants=8, repetitions=3, box_kg=5.0).version
    assert human_dataset.reference_version() != data.version


def test_lifts_look_like_the_papers_mean_trajectories(data: HumanMotionData) -> None:
    squat = np.degrees(data.theta[0])
    assert np.all((squat.max(axis=1) > 90) & (squat.max(axis=1) < 110))
    assert abs(squat[0].max() - squat[1].max()) < 5  # on the diagonal
    left, right = np.degrees(data.angle("stoop_left", "left")), np.degrees(
        data.angle("stoop_left", "right")
    )
    assert left.max() - right.max() > 15  # off the diagonal, box side deeper
    mass = data.meta["mean_mass_kg"]
    for motion, box, other in (("stoop_left", "left", "right"), ("stoop_right", "right", "left")):
        # The non-box leg is a prop: about 5 % of the box-side leg's moment or less
        # and at most about 0.1 Nm/kg (what the paper's utilities imply, see
        # controller.sim.biomechanics), never a flexion moment.
        prop = data.torque(motion, other)
        assert prop.max() < 0.05 * data.torque(motion, box).max()
        assert prop.max() / mass < 0.1 and prop.min() >= 0.0
        assert np.all(prop[:11] == 0.0)  # the first tenth: the hips have not moved back
    for m in range(3):
        start, end = data.theta[m, :, 0], data.theta[m, :, -1]
        assert np.allclose(start, end, atol=1e-6)  # standing to standing
        assert 35 <= int(np.argmax(data.theta[m].sum(axis=0))) <= 60
    # 10 kg: 1.5-2 Nm/kg per loaded hip at the peak (an assumption, see
    # test_biomechanics); the squat's two hips together above the stoop's total, the
    # order Van der Have et al. 2019 (the paper's data source) report.
    squat_total = data.tau[0].sum(axis=0).max() / mass
    stoop_total = data.tau[1].sum(axis=0).max() / mass
    assert 1.5 < squat_total / 2.0 < 2.0
    assert 2.6 < stoop_total < 3.8
    assert squat_total > stoop_total


def test_walking_cycle(data: HumanMotionData) -> None:
    walk = np.degrees(data.theta[3])
    assert np.all((np.ptp(walk, axis=1) > 32) & (np.ptp(walk, axis=1) < 50))
    assert np.corrcoef(walk[0], walk[1])[0, 1] < -0.5
    assert walk[0, 0] > 20  # left heel strike: left hip flexed
    tau = data.tau[3] / data.meta["mean_mass_kg"]
    assert 0.5 < tau.max() < 1.0 and -1.2 < tau.min() < -0.5


def test_write_and_load(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "human.json"
    written = write_reference_dataset(path)
    loaded = HumanMotionData.load(path)
    assert loaded.version == written.version
    assert np.allclose(loaded.theta, written.theta) and np.allclose(loaded.tau, written.tau)
    assert written.meta["participants"] == human_dataset.DEFAULT_PARTICIPANTS


def test_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError):
        reference_dataset(participants=0)
    with pytest.raises(ValueError):
        reference_dataset(box_kg=-1.0)
