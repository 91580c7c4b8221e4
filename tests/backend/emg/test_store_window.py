"""A time window reads only the chunks it overlaps (regression: every window
decompressed the whole file: 1 s for an empty window of a 3.25M-row recording)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from backend.emg import store


def _file(folder: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Any, Any]:
    monkeypatch.setattr(store, "CHUNK_ROWS", 100)
    t = np.arange(1000) / 100.0  # 10 chunks of 1 s
    x = np.random.default_rng(3).normal(0, 1e-4, (1000, 2))
    w = store.EmgWriter(folder / "1.emgc", ["a", "b"], 100.0)
    w.append(t, x)
    w.close()
    return folder / "1.emgc", t, x


def test_a_window_decompresses_only_its_chunks(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    path, t, x = _file(tmp_path, monkeypatch)
    calls: list[int] = []
    real = store._unshuffle

    def counting(data: bytes, dtype: Any, n: int, planes: Any = None) -> Any:
        calls.append(n)
        return real(data, dtype, n, planes)

    monkeypatch.setattr(store, "_unshuffle", counting)
    got_t, got_x = store.read_window(path, 3.2, 3.5)
    np.testing.assert_array_equal(got_t, t[320:350])
    np.testing.assert_allclose(got_x, x[320:350].astype(np.float32))
    assert len(calls) == 2  # one chunk: its timestamps and its samples
    calls.clear()
    empty_t, empty_x = store.read_window(path, 50.0, 60.0)
    assert empty_t.size == 0 and empty_x.shape == (0, 2) and calls == []
    calls.clear()
    got_t, _ = store.read_window(path, 2.95, 4.05)  # spans three chunks
    np.testing.assert_array_equal(got_t, t[295:405])
    assert len(calls) == 6
