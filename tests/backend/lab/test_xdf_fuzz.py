"""The XDF reader fuzzed with generated files: recordings as LabRecorder writes them,
then cut short, overwritten, with sizes inflated and chunks inserted, dropped or
repeated. Whatever the bytes, the reader and the import's summary either succeed or
raise the reader's own `XdfError`, and never allocate beyond the limits they are
given. `EXOSTUDY_FUZZ_EXAMPLES=...` (as for the API fuzzing) digs deeper."""

from __future__ import annotations

import os
import tempfile
import tracemalloc
from pathlib import Path

import numpy as np
from hypothesis import given, settings

from backend.lab import xdf_child, xdf_reader
from backend.lab.xdf_reader import XdfError, XdfLimits
from tests.backend.lab.xdf_strategies import spoiled

#: Files per run: 200 by default, a few seconds.
EXAMPLES = 50 * int(os.environ.get("EXOSTUDY_FUZZ_EXAMPLES", "4"))
#: Limits well under what the generated files may declare.
LIMITS = XdfLimits(max_streams=4, max_chunks=64, max_samples=200, max_clock_offsets=12,
                   max_decoded_bytes=64 * 1024)
#: What the reader may hold besides the decoded data: its bookkeeping, the XML parser's
#: tree of one header, numpy's temporaries of one chunk.
OVERHEAD = 256 * 1024


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None)
@given(spoiled())
def test_any_bytes_are_read_or_refused_within_the_limits(data: bytes) -> None:
    tracemalloc.start()
    try:
        try:
            got: xdf_reader.XdfFile | None = xdf_reader.read(data, LIMITS)
        except XdfError:
            got = None
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= LIMITS.max_decoded_bytes + 2 * len(data) + OVERHEAD
    if got is None:
        return
    assert got.decoded_bytes <= LIMITS.max_decoded_bytes
    assert sum(s.time_stamps.size for s in got.streams) <= LIMITS.max_samples
    built = sum(s.time_stamps.nbytes + (s.values.nbytes if isinstance(s.values, np.ndarray)
                                        else 0) for s in got.streams)
    assert built <= got.decoded_bytes
    for s in got.streams:
        assert np.isfinite(s.time_stamps).all()
        assert np.isfinite(s.clock_times).all() and np.isfinite(s.clock_values).all()
    # What the child does next: clocks, the tick stream's checks, the summary.
    with tempfile.TemporaryDirectory() as folder:
        try:
            rows = xdf_child.summarize(got, Path(folder))
        except XdfError:
            return
    assert [r["stream_id"] for r in rows] == [s.info.stream_id for s in got.streams]
