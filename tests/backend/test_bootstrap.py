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


def test_builders_racing_for_the_same_default_each_write_a_whole_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two servers (or two threads of one) that build the same missing default at once:
    each writes a file of its own and renames it whole onto the path, so neither fails
    and the path never holds a half-written set. The save is slowed down so the two
    writes overlap, as they did with one shared temporary name."""
    import threading
    import time

    path = bootstrap.utilities_path(tmp_path, 25.0)
    made = bootstrap.ensure_utilities(path, 25.0)
    path.unlink()
    monkeypatch.setattr(human_dataset, "reference_dataset", lambda: None)
    monkeypatch.setattr(bootstrap, "compute_utilities", lambda _h, _p: made)
    started = threading.Barrier(2)
    real_save = UtilitySet.save

    def slow_save(self: UtilitySet, target: Path) -> None:
        started.wait(5)  # both writers are inside save before either renames
        real_save(self, target)
        time.sleep(0.05)

    monkeypatch.setattr(UtilitySet, "save", slow_save)
    errors: list[BaseException] = []

    def build() -> None:
        try:
            bootstrap.ensure_utilities(path, 25.0)
        except BaseException as exc:  # any failure is the finding
            errors.append(exc)

    threads = [threading.Thread(target=build) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert errors == []
    assert UtilitySet.load(path).to_json() == made.to_json()
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left
    assert oct(path.stat().st_mode & 0o777) == oct(0o644)
