"""The XDF reading process: it returns a small summary and writes the tick columns to
private files that go away after the import, and every way it can fail (its memory
ceiling, its time limit, any exception, a signal) refuses the file with `XdfError`
(issue 28: pyxdf took the child's MemoryError for a damaged chunk and carried on)."""

from __future__ import annotations

import math
import os
import stat
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from backend.lab import xdf_child, xdf_reader
from backend.lab.lsl_outlets import TICK_CHANNEL_NAMES
from backend.lab.xdf_reader import XdfError, XdfLimits
from tests.backend.lab import xdf_hostile
from tests.backend.lab.xdf_writer import XdfStream, write_xdf


@pytest.fixture
def open_umask() -> Iterator[None]:
    """Files created as if every account could read them by default (umask 0)."""
    old = os.umask(0)
    try:
        yield
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_the_tick_stream_name_is_the_outlets() -> None:
    from backend.lab import lsl_outlets

    assert xdf_child.TICK_STREAM_TYPE == "ExoskeletonTicks"
    assert "seq" in TICK_CHANNEL_NAMES and xdf_child.SEQ_CHANNEL == "seq"
    assert xdf_child.TICK_STREAM_TYPE in Path(lsl_outlets.__file__).read_text()


def test_a_summary_comes_back_and_the_files_stay_private(tmp_path: Path,
                                                         open_umask: None) -> None:
    work = tmp_path / "xdf-work"
    data = xdf_hostile.tick_stream(20)
    with xdf_child.parsed(data, XdfLimits(), work, 60.0) as streams:
        (tick,) = streams
        assert (tick.name, tick.type, tick.samples) == ("ExoStudy", "ExoskeletonTicks", 20)
        assert tick.channels == list(TICK_CHANNEL_NAMES) and tick.channel_count == 15
        assert (tick.first_time, tick.last_time) == (50.0, 50.19)
        assert tick.ticks is not None
        folder = tick.ticks.parent
        assert _mode(work) == 0o700 and _mode(folder) == 0o700
        for name in (xdf_child.UPLOAD, xdf_child.SUMMARY, tick.ticks.name):
            assert _mode(folder / name) == 0o600, name
        assert (folder / xdf_child.UPLOAD).read_bytes() == data
        cols = np.load(tick.ticks)
        np.testing.assert_array_equal(cols[:, 0], [50.0 + i / 100 for i in range(20)])
        np.testing.assert_array_equal(cols[:, 1], np.arange(1000, 1020))
    assert not folder.exists() and list(work.iterdir()) == []


def test_the_clock_offsets_are_applied_in_the_child(tmp_path: Path) -> None:
    stream = XdfStream("EMG", "EMG", ["a"], 100.0, "double64", [10.0, 11.0], [[0.0], [1.0]],
                       clock_offsets=[(10.0, 2.5), (15.0, 2.5)])
    with xdf_child.parsed(write_xdf([stream]), XdfLimits(), tmp_path, 60.0) as streams:
        assert (streams[0].first_time, streams[0].last_time) == (12.5, 13.5)
        assert streams[0].ticks is None


@pytest.mark.parametrize(("script", "words"), [
    ("raise RuntimeError('a bug in the reader')",
     "cannot be read: RuntimeError: a bug in the reader"),
    ("import os, signal; os.kill(os.getpid(), signal.SIGKILL)", "stopped (SIGKILL)"),
    ("raise MemoryError", "needs more than"),
    ("import sys; sys.exit(3)", "needs more than"),
    ("import sys; sys.exit(2)", "cannot be read: no message"),
    ("import time; time.sleep(60)", "longer than 0.5 s (the server's xdf_parse_seconds)"),
])
def test_every_failure_of_the_child_refuses_the_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, script: str, words: str) -> None:
    monkeypatch.setattr(xdf_child, "_command",
                        lambda *_: [sys.executable, "-c", script])
    with pytest.raises(XdfError) as caught, \
            xdf_child.parsed(b"XDF:", XdfLimits(), tmp_path, 0.5):
        raise AssertionError("a failed child gave a summary")
    assert words in str(caught.value)
    assert list(tmp_path.iterdir()) == []  # the upload is removed


def test_the_memory_ceiling_refuses_the_file(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # The real child, given less address space than decoding needs (no base allowance:
    # the first large allocation fails), refuses rather than returning what it had.
    monkeypatch.setattr(xdf_child, "CHILD_BASE_BYTES", 0)
    n = 200_000
    data = write_xdf([XdfStream("EMG", "EMG", ["a"], 100.0, "int8",
                                [float(i) for i in range(n)], [[1]] * n)])
    limits = XdfLimits(max_decoded_bytes=5_000_000)
    with pytest.raises(XdfError, match=r"needs more than \d+ bytes of memory"), \
            xdf_child.parsed(data, limits, tmp_path, 60.0):
        raise AssertionError("the child read a file beyond its memory")


def _summarize(data: bytes, folder: Path) -> list[dict[str, object]]:
    return xdf_child.summarize(xdf_reader.read(data, decode_strings=False), folder)


@pytest.mark.parametrize(("spoiled", "words"), [
    ({"fmt": "string", "seq": ["x"] * 20}, "seq channel holds strings"),
    ({"seq": [1000.0] * 19 + [math.nan]}, "sample 19 has seq nan"),
    ({"seq": [1000.0] * 19 + [-math.inf]}, "sample 19 has seq -inf"),
    ({"seq": [1000.5] * 20}, "sample 0 has seq 1000.5"),
    ({"seq": [-1.0] * 20}, "sample 0 has seq -1.0"),
    ({"seq": [2.0**60] * 20}, "not a whole sample number from 0 to 9007199254740992"),
    ({"labels": [*TICK_CHANNEL_NAMES[1:], "seq"], "channels": 3},
     "declares 3 channels but labels 15"),
    ({"labels": ["a", "b"]}, "needs exactly one channel labelled 'seq', has 0"),
    ({"labels": ["seq", "seq"]}, "needs exactly one channel labelled 'seq', has 2"),
])
def test_every_field_of_a_tick_stream_is_checked(tmp_path: Path, spoiled: dict[str, Any],
                                                 words: str) -> None:
    with pytest.raises(XdfError) as caught:
        _summarize(xdf_hostile.tick_stream(**spoiled), tmp_path)
    assert words in str(caught.value)
    assert list(tmp_path.iterdir()) == []  # no tick columns written


def test_a_clock_that_overflows_is_refused(tmp_path: Path) -> None:
    # Time stamps and offsets within the range (1e10 s) whose fitted line carries the
    # stamps beyond it: refused, not stored as a huge or infinite time.
    steep = write_xdf([XdfStream("EMG", "EMG", ["a"], 100.0, "double64", [1e9, 2e9],
                                 [[0.0], [1.0]], clock_offsets=[(0.0, 0.0), (1e-3, 9e9)])])
    with pytest.raises(XdfError, match=r"out of the range ±1e\+10 s"):
        _summarize(steep, tmp_path)
