"""ExoStudy's XDF reader: files written as LabRecorder writes them read exactly as
written, and as pyxdf (an independent reader, used here as the oracle) reads them; the
hostile files of issues 23 and 28 are refused before anything they declare is
allocated, each naming the chunk and what is wrong."""

from __future__ import annotations

import logging
import math
import struct
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import pyxdf
from hypothesis import HealthCheck, given, settings

from backend.lab import xdf_clock, xdf_reader
from backend.lab.xdf_reader import XdfError, XdfLimits
from tests.backend.lab import xdf_hostile
from tests.backend.lab.xdf_strategies import recordings
from tests.backend.lab.xdf_writer import XdfStream, chunk, header_xml, write_xdf

# pyxdf says so for every stream whose clock it splits; nothing to see in a test.
logging.getLogger("pyxdf").setLevel(logging.ERROR)


def _expected_stamps(s: XdfStream) -> list[float]:
    """Time stamps as the format defines them: a sample without one comes one nominal
    interval after the stream's previous sample (the first after 0)."""
    out, last = [], 0.0
    tdiff = 1.0 / s.srate if s.srate > 0 else 0.0
    for k, t in enumerate(s.stamps):
        last = t if s.stamped is None or s.stamped[k] else last + tdiff
        out.append(last)
    return out


def _peak_bytes(call: Any) -> tuple[Any, int]:
    """(what `call()` returned or raised, the peak bytes it allocated)."""
    tracemalloc.start()
    try:
        try:
            result = call()
        except XdfError as exc:
            result = exc
        return result, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(recordings())
def test_a_recording_reads_as_written(written: list[XdfStream]) -> None:
    got = xdf_reader.read(write_xdf(written))
    assert not got.truncated and [s.info.name for s in got.streams] == \
        [w.name for w in written]
    for s, w in zip(got.streams, written, strict=True):
        assert s.info.channel_count == len(w.channels) and s.info.labels == tuple(w.channels)
        assert s.info.channel_format == w.fmt and s.info.nominal_srate == w.srate
        assert s.time_stamps.tolist() == _expected_stamps(w)
        if w.fmt == "string":
            assert s.values == [[str(v) for v in row] for row in w.rows]
        else:
            assert isinstance(s.values, np.ndarray)
            want = np.asarray(w.rows, dtype=s.values.dtype).reshape(len(w.rows),
                                                                     len(w.channels))
            np.testing.assert_array_equal(s.values, want)
        assert s.clock_times.tolist() == [t for t, _ in w.clock_offsets]
        assert s.clock_values.tolist() == [v for _, v in w.clock_offsets]
    # Without the text of string streams, the rest is the same.
    lean = xdf_reader.read(write_xdf(written), decode_strings=False)
    for s, w in zip(lean.streams, written, strict=True):
        assert s.time_stamps.tolist() == _expected_stamps(w)
        assert (s.values is None) == (w.fmt == "string")


@settings(max_examples=15, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(recordings())
def test_the_reader_agrees_with_pyxdf(tmp_path: Path, written: list[XdfStream]) -> None:
    data = write_xdf(written)
    path = tmp_path / "oracle.xdf"
    path.write_bytes(data)
    theirs, _ = pyxdf.load_xdf(str(path), synchronize_clocks=True, dejitter_timestamps=False)
    ours = xdf_reader.read(data).streams
    assert [s.info.stream_id for s in ours] == [int(t["info"]["stream_id"]) for t in theirs]
    for s, t in zip(ours, theirs, strict=True):
        assert s.info.name == t["info"]["name"][0]
        assert s.info.type == t["info"]["type"][0]
        stamps = xdf_clock.synchronize(s.time_stamps, s.clock_times, s.clock_values)
        np.testing.assert_allclose(stamps, t["time_stamps"], rtol=0, atol=1e-6)
        if s.info.channel_format == "string":
            assert s.values == t["time_series"]
        else:
            np.testing.assert_array_equal(s.values, t["time_series"])
            assert isinstance(s.values, np.ndarray)
            if s.values.size:  # pyxdf gives a stream without samples as float64
                assert s.values.dtype == t["time_series"].dtype


def test_a_sample_never_reads_past_its_chunk() -> None:
    # Issue 28: the least-size check passed (1 string sample in 3 bytes), and the sample's
    # time stamp was read from the next chunk on; what followed declared 50 million
    # samples (2 GB in the parser).
    data = xdf_hostile.past_its_end()
    result, peak = _peak_bytes(lambda: xdf_reader.read(data))
    assert isinstance(result, XdfError)
    assert "(Samples, stream 1): sample 0's time stamp runs past the chunk's end" in \
        str(result)
    assert peak < 200_000


@pytest.mark.parametrize(("data", "words"), [
    (xdf_hostile.declaring(50_000_000), "declares 50000000 samples"),
    (xdf_hostile.declaring(30_000_000, 3), "declares 30000000 samples of 3 string"),
    (xdf_hostile.declaring(5_000_000, 100, "double64"), "but the chunk holds 809"),
    (xdf_hostile.declaring(2**32 - 1, 1, "double64"), "declares 4294967295 samples"),
    (b"XDF:" + chunk(2, struct.pack("<I", 1) + header_xml("x", "EEG", 250_000_000, 1,
                                                          "float32")), "channel_count"),
])
def test_declared_sizes_are_checked_before_allocation(data: bytes, words: str) -> None:
    result, peak = _peak_bytes(lambda: xdf_reader.read(data))
    assert isinstance(result, XdfError) and words in str(result), result
    assert peak < 200_000


def _limited(**fields: int) -> XdfLimits:
    return XdfLimits(**fields)


@pytest.mark.parametrize(("data", "limits", "words"), [
    (write_xdf([xdf_hostile.small_stream(f"s{i}") for i in range(3)]),
     _limited(max_streams=2), "more than 2 streams (the server's xdf_max_streams)"),
    (write_xdf([xdf_hostile.small_stream()]) + chunk(5, b"") * 40, _limited(max_chunks=40),
     "more than 40 chunks (the server's xdf_max_chunks)"),
    (write_xdf([xdf_hostile.small_stream(n=50)]), _limited(max_samples=49),
     "more than 49 samples in the file (the server's xdf_max_samples)"),
    (xdf_hostile.clock_offsets(20), _limited(max_clock_offsets=19),
     "more than 19 clock offsets in the file (the server's xdf_max_clock_offsets)"),
    (write_xdf([xdf_hostile.small_stream(n=50)]), _limited(max_decoded_bytes=50 * 24),
     "decode to more than 1200 bytes (the server's xdf_max_decoded_bytes)"),
])
def test_each_limit_refuses_a_file_beyond_it(data: bytes, limits: XdfLimits,
                                             words: str) -> None:
    with pytest.raises(XdfError, match=None) as caught:
        xdf_reader.read(data, limits)
    assert words in str(caught.value)


def test_the_limits_hold_for_a_file_that_fits_them() -> None:
    data = write_xdf([xdf_hostile.small_stream(n=50)])
    got = xdf_reader.read(data, _limited(max_samples=50, max_decoded_bytes=50 * 24 + 32))
    assert got.decoded_bytes == 50 * 24 + 32
    assert got.streams[0].time_stamps.size == 50


def test_a_flood_of_boundary_chunks_stops_at_the_chunk_limit() -> None:
    # Issue 28: 2 million boundary chunks in 8 MB took 11.6 s; the default limit ends the
    # walk at the millionth.
    data = write_xdf([xdf_hostile.small_stream()]) + b"\x01\x02\x05\x00" * 2_000_000
    with pytest.raises(XdfError, match="more than 1000000 chunks"):
        xdf_reader.read(data)


def _one_stream(xml: bytes, samples: bytes = b"") -> bytes:
    return b"XDF:" + chunk(2, struct.pack("<I", 1) + xml) + samples


@pytest.mark.parametrize(("data", "words"), [
    (_one_stream(header_xml("x", "EEG", 1, "NaN", "double64")), "nominal_srate 'NaN'"),
    (_one_stream(header_xml("x", "EEG", 1, "inf", "double64")), "nominal_srate 'inf'"),
    (_one_stream(header_xml("x", "EEG", 1, "-1", "double64")), "nominal_srate '-1'"),
    (_one_stream(header_xml("x", "EEG", 1, "fast", "double64")), "nominal_srate 'fast'"),
    (_one_stream(header_xml("x", "EEG", "²", 1, "double64")), "channel_count '²'"),
    (_one_stream(header_xml("x", "EEG", 0, 1, "double64")), "channel_count '0'"),
    (_one_stream(header_xml("x", "EEG", 1, 1, "float128")), "channel_format 'float128'"),
    (_one_stream(b"<info><name>x</name>"), "is not XML"),
    (_one_stream(b'<!DOCTYPE info [<!ENTITY a "aaaa">]><info>&a;</info>'), "entities"),
    (write_xdf([XdfStream("x", "EEG", ["a"], 1.0, "double64", [1.0, math.nan],
                          [[0.0], [0.0]])]), "sample 1 has the time stamp nan"),
    (write_xdf([XdfStream("x", "EEG", ["a"], 1.0, "double64", [-math.inf], [[0.0]])]),
     "sample 0 has the time stamp -inf"),
    (write_xdf([XdfStream("x", "EEG", ["a"], 1.0, "string", [math.inf], [["a"]])]),
     "sample 0 has the time stamp inf"),
    (write_xdf([XdfStream("x", "EEG", ["a"], 1.0, "double64", [1.0], [[0.0]],
                          clock_offsets=[(math.nan, 1.0)])]), "not a finite number"),
])
def test_every_header_field_and_time_is_checked(data: bytes, words: str) -> None:
    with pytest.raises(XdfError) as caught:
        xdf_reader.read(data)
    assert words in str(caught.value)


def _stream_and(body: bytes, fmt: str = "double64") -> bytes:
    return _one_stream(header_xml("x", "EEG", 1, 100, fmt), body)


@pytest.mark.parametrize(("data", "words"), [
    # A time stamp field of 5 bytes (XDF has 0 or 8).
    (_stream_and(chunk(3, struct.pack("<I", 1) + bytes([1, 1, 5]) + bytes(8))),
     "time stamp field of 5 bytes"),
    # One sample too many bytes: the chunk holds more than its samples.
    (_stream_and(chunk(3, struct.pack("<I", 1) + bytes([1, 1, 8]) + bytes(17))),
     "which take between 9 and 17 bytes, but the chunk holds 18"),
    # A string sample whose length runs past the chunk.
    (_stream_and(chunk(3, struct.pack("<I", 1) + bytes([1, 1, 0, 1, 200]) + b"ab"),
                 "string"), "sample 0, channel 0 runs past the chunk's end"),
    (_stream_and(chunk(3, struct.pack("<I", 1) + bytes([1, 1, 0, 1, 1]) + b"ab"),
                 "string"), "1 bytes after its last sample"),
    (_stream_and(chunk(3, struct.pack("<I", 2) + bytes([1, 0]))),
     "(Samples, stream 2): no header for the stream"),
    (_stream_and(chunk(2, struct.pack("<I", 1) + header_xml("y", "EEG", 1, 1, "int8"))),
     "a second header for the stream"),
    (_stream_and(chunk(4, struct.pack("<Id", 1, 1.0))), "not 16 (two doubles)"),
    (_stream_and(chunk(3, b"\x01")), "too short for its stream id"),
    (_stream_and(bytes([3]) + b"\x00\x00\x00"), "a length field of 3 bytes"),
    (_stream_and(bytes([1, 1]) + b"\x05"), "a length of 1, too short for its tag"),
    (b"PK\x03\x04", "not an XDF file"),
])
def test_a_malformed_chunk_is_refused(data: bytes, words: str) -> None:
    with pytest.raises(XdfError) as caught:
        xdf_reader.read(data)
    assert words in str(caught.value)


def test_a_file_cut_short_is_read_up_to_its_last_whole_chunk() -> None:
    stream = xdf_hostile.small_stream(n=10)
    stream.chunks = [4, 6]
    data = write_xdf([stream])
    whole = xdf_reader.read(data)
    assert not whole.truncated and whole.streams[0].time_stamps.size == 10
    # Cut inside the second Samples chunk: the first chunk's 4 samples remain.
    second = data.index(chunk(3, stream.sample_chunks(1)[1]))
    cut = xdf_reader.read(data[:second + 30])
    assert cut.truncated
    assert cut.streams[0].time_stamps.tolist() == stream.stamps[:4]


def test_unknown_chunks_and_footers_are_passed_over() -> None:
    stream = xdf_hostile.small_stream(n=3)
    data = write_xdf([stream]) + chunk(77, b"anything") + chunk(6, struct.pack("<I", 1)
                                                                + b"<not xml")
    got = xdf_reader.read(data)
    assert got.streams[0].time_stamps.tolist() == stream.stamps
