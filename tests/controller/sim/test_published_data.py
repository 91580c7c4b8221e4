"""The simulated reference data against published measurements it was not built from.

The fixtures under `tests/fixtures/` (provenance and checksums in its README) are never
read by the generator; a test here fails if the simulation drifts outside the
published between-subject spread.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from controller.human_data import HumanMotionData
from controller.sim.human_dataset import reference_dataset

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
SCHWARTZ = FIXTURES / "schwartz2008_walking_hip.csv"
SCHWARTZ_SHA256 = "1e876a8235ff85c0c8c6a82c989f5c0a3228159699641b41241621bc136068d5"


@pytest.fixture(scope="module")
def reference() -> HumanMotionData:
    return reference_dataset()


@pytest.fixture(scope="module")
def schwartz() -> np.ndarray:
    assert hashlib.sha256(SCHWARTZ.read_bytes()).hexdigest() == SCHWARTZ_SHA256
    return np.loadtxt(SCHWARTZ, delimiter=",", skiprows=1)


def _z(ours: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How many published standard deviations ours is from the published mean."""
    return (ours - (lo + hi) / 2.0) / ((hi - lo) / 2.0)


def test_walking_within_the_normative_spread(
    reference: HumanMotionData, schwartz: np.ndarray
) -> None:
    pct = schwartz[:, 0]
    s = np.linspace(0.0, 100.0, 101)
    mass = float(reference.meta["mean_mass_kg"])
    for leg in ("left", "right"):
        # Each leg's own cycle from its own foot contact (the right leg is half a
        # cycle after the left in the dataset, which starts at left foot contact).
        shift = 0.0 if leg == "left" else 50.0
        at = np.mod(pct + shift, 100.0)
        theta = np.degrees(np.interp(at, s, reference.angle("walking", leg)))
        tau = np.interp(at, s, reference.torque("walking", leg)) / mass
        z_angle = _z(theta, schwartz[:, 1], schwartz[:, 2])
        z_moment = _z(tau, schwartz[:, 3], schwartz[:, 4])
        assert np.abs(z_angle).max() <= 2.0, (leg, z_angle)
        assert np.mean(np.abs(z_moment) <= 2.0) >= 0.9, (leg, z_moment)
        assert np.abs(z_moment).max() <= 2.5, (leg, z_moment)
        # On average closer to the mean than one published SD.
        assert np.sqrt(np.mean(z_angle**2)) < 1.0 and np.sqrt(np.mean(z_moment**2)) < 1.0


def test_the_fixture_is_what_its_readme_says(schwartz: np.ndarray) -> None:
    assert schwartz.shape == (51, 5)
    assert np.array_equal(schwartz[:, 0], np.arange(0.0, 101.0, 2.0))
    assert (schwartz[:, 2] > schwartz[:, 1]).all() and (schwartz[:, 4] > schwartz[:, 3]).all()
    assert SCHWARTZ_SHA256 in (FIXTURES / "README.md").read_text()
