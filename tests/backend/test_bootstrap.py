"""The embedded default utilities: computed once, then loaded at every start without
recomputing the reference dataset, and rebuilt when they were computed from other data."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from backend import bootstrap
from controller.decision.utility_function import UtilitySet
from controller.sim import human_dataset


def test_utilities_are_computed_once_then_loaded_and_rebuilt_from_other_data(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = bootstrap.utilities_path(tmp_path, 25.0)
    made = bootstrap.ensure_utilities(path, 25.0)
    assert path.is_file() and made.human_version == human_dataset.reference_version()

    # A start with the file in place reads it and never builds the dataset.
    def refuse() -> None:
        raise AssertionError("the reference dataset was computed for a cached set")

    with monkeypatch.context() as patch:
        patch.setattr(human_dataset, "reference_dataset", refuse)
        again = bootstrap.ensure_utilities(path, 25.0)
    assert again.to_json() == made.to_json()

    # Computed from another version of the dataset: rebuilt, and the file replaced.
    stale = dataclasses.replace(made, human_version="sim-0+000000000000")
    stale.save(path)
    assert UtilitySet.load(path).human_version == "sim-0+000000000000"
    rebuilt = bootstrap.ensure_utilities(path, 25.0)
    assert rebuilt.human_version == human_dataset.reference_version()
    assert UtilitySet.load(path).human_version == rebuilt.human_version
    # Another precompression: rebuilt for it.
    assert bootstrap.ensure_utilities(path, 30.0).precompression_pct == 30.0
