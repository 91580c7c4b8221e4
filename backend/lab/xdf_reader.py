"""An XDF reader that decodes only what a file holds, within stated limits.

XDF 1.x, the format LabRecorder writes: `XDF:`, then chunks of
`[NumLengthBytes: 1, 4 or 8][Length][Tag: u16][Content]`, where Length counts the tag
and the content. Tags: 1 FileHeader (XML), 2 StreamHeader (stream id u32 + XML),
3 Samples (stream id, a variable-length sample count, the samples), 4 ClockOffset
(stream id, collection time f64, offset f64), 5 Boundary (a fixed UUID), 6 StreamFooter
(stream id + XML). A sample is `[TimeStampBytes: 0 or 8][TimeStamp f64 if 8]` and its
values: fixed-width little-endian numbers, or per channel a variable-length byte count
and that many bytes of text. A sample without a time stamp is one nominal interval
after the stream's previous one.

Readers that allocate what a chunk declares, then read on from the file instead of the
chunk, let a few hundred bytes claim gigabytes, and let a chunk that declares more than
it holds read into the next (issues 23 and 28). This one reads in two passes. The first
walks the chunks, reads the stream headers and clock offsets, checks each Samples
chunk's declared count against the chunk's own bytes, and adds up what decoding will
build against `XdfLimits`; nothing sized by the file is allocated before those checks
pass. The second decodes each Samples chunk into arrays sized by the first, and no
sample reads past the end of its chunk. Anything malformed raises `XdfError` naming the
byte offset; nothing is skipped or guessed, except an incomplete last chunk (a
recording stopped mid-write), which is left out.
"""

from __future__ import annotations

import math
import re
import struct
from array import array
from dataclasses import dataclass, field
from typing import Any
from xml.etree import ElementTree

import numpy as np
from numpy.typing import NDArray

MAGIC = b"XDF:"
FILE_HEADER, STREAM_HEADER, SAMPLES, CLOCK_OFFSET, BOUNDARY, STREAM_FOOTER = 1, 2, 3, 4, 5, 6
_TAG_NAMES = {1: "FileHeader", 2: "StreamHeader", 3: "Samples", 4: "ClockOffset",
              5: "Boundary", 6: "StreamFooter"}
#: Little-endian dtype of each numeric channel format; strings have none.
FORMATS: dict[str, str | None] = {"double64": "<f8", "float32": "<f4", "int64": "<i8",
                                  "int32": "<i4", "int16": "<i2", "int8": "i1",
                                  "string": None}
#: Ceiling of `XdfLimits.max_channels` (and of the xdf_max_channels setting).
MAX_CHANNELS = 65_536
#: Ceiling of `XdfLimits.max_header_bytes`: a header with a label, unit and type for
#: each of 65 536 channels is about 6 MB; the XML parser takes several times that.
MAX_HEADER_BYTES = 16 * 1024**2
#: Largest time (s, either sign) a time stamp or a clock offset may hold. LSL clocks
#: count from boot, and outlets that stamp with Unix time are near 1.7e9; 1e10 s is 317
#: years. Within it, every difference, median or x 1000 built from them stays finite.
MAX_TIME = 1e10
#: Memory a decoded string value costs beyond its text (a str object and its list slot),
#: and a decoded string sample beyond its values (its list): CPython 3.11, 64-bit.
_STRING_VALUE_COST = 8 + 50
_STRING_SAMPLE_COST = 56
#: What the reader keeps per Samples chunk between the passes (four 8-byte integers).
_CHUNK_RECORD_COST = 32


class XdfError(ValueError):
    """The file is not well-formed XDF, or it would take more than the limits allow."""


@dataclass(frozen=True)
class XdfLimits:
    """What one file may make the reader build (the server's settings fill these in)."""

    max_streams: int = 100
    max_chunks: int = 1_000_000
    max_samples: int = 20_000_000
    max_clock_offsets: int = 50_000
    max_decoded_bytes: int = 1024**3
    #: Channels one stream may declare (at most MAX_CHANNELS).
    max_channels: int = 4096
    #: Bytes of one stream header's XML (at most MAX_HEADER_BYTES).
    max_header_bytes: int = 1024**2


@dataclass(frozen=True)
class StreamInfo:
    """The fields of a stream header that the reader checked."""

    stream_id: int
    name: str
    type: str
    source_id: str
    channel_count: int
    channel_format: str
    nominal_srate: float
    #: Labels of `desc/channels/channel`, as many as the header lists (may differ from
    #: `channel_count`: the format does not require them).
    labels: tuple[str, ...]
    #: Units of the same channels (`desc/channels/channel/unit`, "" where not given).
    units: tuple[str, ...] = ()


@dataclass
class XdfStream:
    """One stream: its header, time stamps as recorded (in its own clock), values
    (samples x channels; a list of rows of text for string streams, None when strings
    were not decoded) and the clock offsets measured while it was recorded."""

    info: StreamInfo
    time_stamps: NDArray[np.float64]
    values: NDArray[Any] | list[list[str]] | None
    clock_times: NDArray[np.float64]
    clock_values: NDArray[np.float64]


@dataclass
class XdfFile:
    """What `read` found: the streams in header order, whether an incomplete last chunk
    was left out, and the bytes decoding built (as counted against the limit)."""

    streams: list[XdfStream]
    truncated: bool
    decoded_bytes: int


@dataclass
class _Pending:
    """A stream between the passes: its Samples chunks as (chunk offset, first sample
    byte, end byte, sample count) quadruples, and its clock offsets."""

    info: StreamInfo
    dtype: np.dtype[Any] | None
    chunks: array[int] = field(default_factory=lambda: array("q"))
    samples: int = 0
    clock_times: array[float] = field(default_factory=lambda: array("d"))
    clock_values: array[float] = field(default_factory=lambda: array("d"))


_VARLEN = {1: "<B", 4: "<I", 8: "<Q"}
_DIGITS = re.compile(r"[0-9]{1,7}")
_DOCTYPE = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


def _varlen(buf: bytes, pos: int, end: int, where: str) -> tuple[int, int] | None:
    """(value, position after it) of a variable-length integer in `buf[pos:end]`; None
    if the bytes end first; XdfError if its width byte is not 1, 4 or 8."""
    if pos >= end:
        return None
    width = buf[pos]
    fmt = _VARLEN.get(width)
    if fmt is None:
        raise XdfError(f"{where}: a length field of {width} bytes (XDF allows 1, 4 or 8)")
    if pos + 1 + width > end:
        return None
    return struct.unpack_from(fmt, buf, pos + 1)[0], pos + 1 + width


def _text(root: ElementTree.Element, path: str) -> str:
    return (root.findtext(path) or "").strip()


def _stream_info(sid: int, xml: bytes, where: str, limits: XdfLimits) -> StreamInfo:
    """The checked fields of a stream header's XML."""
    most_bytes = min(limits.max_header_bytes, MAX_HEADER_BYTES)
    if len(xml) > most_bytes:
        raise XdfError(f"{where}: a stream header of {len(xml)} bytes (at most "
                       f"{most_bytes}, the server's xdf_max_header_bytes)")
    if _DOCTYPE.search(xml):
        raise XdfError(f"{where}: the stream header declares a document type or entities, "
                       "which stream headers never need")
    try:
        root = ElementTree.fromstring(xml.decode("utf-8", "replace"))
    except ElementTree.ParseError as exc:
        raise XdfError(f"{where}: the stream header is not XML ({exc})") from exc
    count = _text(root, "channel_count")
    most = min(limits.max_channels, MAX_CHANNELS)
    if not _DIGITS.fullmatch(count) or not 1 <= int(count) <= most:
        raise XdfError(f"{where}: channel_count {count[:20]!r} must be a whole number "
                       f"from 1 to {most} (the server's xdf_max_channels)")
    fmt = _text(root, "channel_format")
    if fmt not in FORMATS:
        raise XdfError(f"{where}: channel_format {fmt[:20]!r} is not one of "
                       f"{sorted(FORMATS)}")
    rate_text = _text(root, "nominal_srate") or "0"
    try:
        rate = float(rate_text)
    except ValueError:
        rate = math.nan
    if not math.isfinite(rate) or rate < 0:
        raise XdfError(f"{where}: nominal_srate {rate_text[:20]!r} must be a finite number "
                       "of samples per second, 0 or more (0: irregular)")
    channels = list(root.iterfind("desc/channels/channel"))
    labels = tuple(_text(ch, "label") for ch in channels)
    units = tuple(_text(ch, "unit") for ch in channels)
    return StreamInfo(stream_id=sid, name=_text(root, "name"), type=_text(root, "type"),
                      source_id=_text(root, "source_id"), channel_count=int(count),
                      channel_format=fmt, nominal_srate=rate, labels=labels, units=units)


def _sample_bounds(stream: _Pending) -> tuple[int, int]:
    """Fewest and most bytes one sample of the stream can take (most: -1 for strings,
    whose text has no upper bound)."""
    ch = stream.info.channel_count
    if stream.dtype is None:
        return 1 + 2 * ch, -1  # flag, and per channel a 1-byte width and a 1-byte length
    width = stream.dtype.itemsize * ch
    return 1 + width, 9 + width


def _decoded_cost(stream: _Pending, samples: int, text_bytes: int,
                  decode_strings: bool) -> int:
    """Bytes decoding `samples` samples of the stream builds (time stamps included)."""
    if stream.dtype is not None:
        return samples * (8 + stream.dtype.itemsize * stream.info.channel_count)
    if not decode_strings:
        return samples * 8
    ch = stream.info.channel_count
    return samples * (8 + _STRING_SAMPLE_COST + ch * _STRING_VALUE_COST) + text_bytes


def require_magic(data: bytes) -> None:
    """XdfError unless `data` starts as an XDF file does."""
    if not data.startswith(MAGIC):
        raise XdfError("not an XDF file (it does not start with 'XDF:')")


def _walk(data: bytes, limits: XdfLimits, decode_strings: bool
          ) -> tuple[dict[int, _Pending], bool, int]:
    """The first pass: (streams by id, truncated, bytes decoding will build)."""
    require_magic(data)
    streams: dict[int, _Pending] = {}
    end_of_file = len(data)
    pos = len(MAGIC)
    chunks = samples = offsets = 0
    decoded = 0
    unpack_from = struct.unpack_from
    while pos < end_of_file:
        where = f"chunk at byte {pos}"
        length = _varlen(data, pos, end_of_file, where)
        if length is None or length[1] + length[0] > end_of_file:
            return streams, True, decoded  # the recording stopped mid-chunk
        size, start = length
        if size < 2:
            raise XdfError(f"{where}: a length of {size}, too short for its tag")
        chunks += 1
        if chunks > limits.max_chunks:
            raise XdfError(f"{where}: more than {limits.max_chunks} chunks "
                           "(the server's xdf_max_chunks)")
        end = start + size
        tag = unpack_from("<H", data, start)[0]
        body = start + 2
        if tag in (STREAM_HEADER, SAMPLES, CLOCK_OFFSET, STREAM_FOOTER):
            name = _TAG_NAMES[tag]
            if end - body < 4:
                raise XdfError(f"{where} ({name}): too short for its stream id")
            sid = unpack_from("<I", data, body)[0]
            where = f"{where} ({name}, stream {sid})"
            body += 4
            stream = streams.get(sid)
            if tag == STREAM_HEADER:
                if stream is not None:
                    raise XdfError(f"{where}: a second header for the stream")
                if len(streams) >= limits.max_streams:
                    raise XdfError(f"{where}: more than {limits.max_streams} streams "
                                   "(the server's xdf_max_streams)")
                info = _stream_info(sid, data[body:end], where, limits)
                fmt = FORMATS[info.channel_format]
                streams[sid] = _Pending(info, None if fmt is None else np.dtype(fmt))
            elif stream is None:
                raise XdfError(f"{where}: no header for the stream comes before it")
            elif tag == SAMPLES:
                count = _varlen(data, body, end, where)
                if count is None:
                    raise XdfError(f"{where}: the sample count runs past the chunk's end")
                n, first = count
                room = end - first
                least, most = _sample_bounds(stream)
                if n * least > room or (most >= 0 and n * most < room):
                    held = f"between {n * least} and {n * most}" if most >= 0 else \
                        f"at least {n * least}"
                    raise XdfError(
                        f"{where}: declares {n} samples of {stream.info.channel_count} "
                        f"{stream.info.channel_format} channels, which take {held} bytes, "
                        f"but the chunk holds {room}")
                samples += n
                if samples > limits.max_samples:
                    raise XdfError(f"{where}: more than {limits.max_samples} samples in "
                                   "the file (the server's xdf_max_samples)")
                decoded += _CHUNK_RECORD_COST + _decoded_cost(stream, n, room,
                                                              decode_strings)
                if decoded > limits.max_decoded_bytes:
                    raise XdfError(f"{where}: the file would decode to more than "
                                   f"{limits.max_decoded_bytes} bytes (the server's "
                                   "xdf_max_decoded_bytes)")
                stream.chunks.extend((pos, first, end, n))
                stream.samples += n
            elif tag == CLOCK_OFFSET:
                if end - body != 16:
                    raise XdfError(f"{where}: holds {end - body} bytes after the stream id, "
                                   "not 16 (two doubles)")
                offsets += 1
                if offsets > limits.max_clock_offsets:
                    raise XdfError(f"{where}: more than {limits.max_clock_offsets} clock "
                                   "offsets in the file (the server's xdf_max_clock_offsets)")
                collected, value = unpack_from("<dd", data, body)
                if not (abs(collected) < MAX_TIME and abs(value) < MAX_TIME):
                    raise XdfError(f"{where}: a clock offset ({collected}, {value}) that "
                                   f"is not a finite number of seconds within "
                                   f"±{MAX_TIME:g} s")
                stream.clock_times.append(collected)
                stream.clock_values.append(value)
                decoded += 16
        # FileHeader, StreamFooter, Boundary and unknown chunks: nothing is read from them.
        pos = end
    return streams, False, decoded


def _decode_numeric(data: bytes, stream: _Pending, stamps: NDArray[np.float64],
                    values: NDArray[Any], last: float, chunk: tuple[int, int, int, int]
                    ) -> float:
    """Decode one Samples chunk of a numeric stream into `stamps` and `values` (its
    rows); the stream's last time stamp after it."""
    pos, first, end, n = chunk
    assert stream.dtype is not None
    ch = stream.info.channel_count
    width = stream.dtype.itemsize * ch
    tdiff = 1.0 / stream.info.nominal_srate if stream.info.nominal_srate > 0 else 0.0
    room = end - first
    if n == 0:
        return last
    # Every sample stamped (as LabRecorder writes them) or none: one view of the bytes.
    if room == n * (9 + width):
        rec = np.frombuffer(data, np.dtype([("f", "u1"), ("t", "<f8"),
                                            ("v", stream.dtype, (ch,))]), n, first)
        if bool((rec["f"] == 8).all()):
            stamps[:] = rec["t"]
            values[:] = rec["v"]
            return float(stamps[-1])
    if room == n * (1 + width):
        rec = np.frombuffer(data, np.dtype([("f", "u1"), ("v", stream.dtype, (ch,))]),
                            n, first)
        if bool((rec["f"] == 0).all()):
            steps = np.full(n + 1, tdiff)
            steps[0] = last
            stamps[:] = np.cumsum(steps)[1:]  # one interval after the other, as written
            values[:] = rec["v"]
            return float(stamps[-1])
    at = first
    for k in range(n):
        if at >= end:
            break
        flag = data[at]
        if flag == 8:
            if at + 9 + width > end:
                break
            last = struct.unpack_from("<d", data, at + 1)[0]
            at += 9
        elif flag == 0:
            if at + 1 + width > end:
                break
            last += tdiff
            at += 1
        else:
            raise XdfError(f"chunk at byte {pos} (Samples, stream {stream.info.stream_id}): "
                           f"sample {k} has a time stamp field of {flag} bytes (0 or 8)")
        stamps[k] = last
        values[k] = np.frombuffer(data, stream.dtype, ch, at)
        at += width
    else:
        if at == end:
            return last
    raise XdfError(f"chunk at byte {pos} (Samples, stream {stream.info.stream_id}): its "
                   f"{n} samples do not fill its {room} bytes exactly")


def _decode_strings(data: bytes, stream: _Pending, stamps: NDArray[np.float64],
                    rows: list[list[str]] | None, last: float,
                    chunk: tuple[int, int, int, int]) -> float:
    """Decode one Samples chunk of a string stream (the text only if `rows` is a list);
    the stream's last time stamp after it."""
    pos, at, end, n = chunk
    where = f"chunk at byte {pos} (Samples, stream {stream.info.stream_id})"
    ch = stream.info.channel_count
    tdiff = 1.0 / stream.info.nominal_srate if stream.info.nominal_srate > 0 else 0.0
    unpack_from = struct.unpack_from
    for k in range(n):
        if at >= end:
            raise XdfError(f"{where}: sample {k} starts past the chunk's end")
        flag = data[at]
        if flag == 8:
            if at + 9 > end:
                raise XdfError(f"{where}: sample {k}'s time stamp runs past the chunk's end")
            last = unpack_from("<d", data, at + 1)[0]
            at += 9
        elif flag == 0:
            last += tdiff
            at += 1
        else:
            raise XdfError(f"{where}: sample {k} has a time stamp field of {flag} bytes "
                           "(0 or 8)")
        stamps[k] = last
        row: list[str] = []
        for c in range(ch):
            length = _varlen(data, at, end, where)
            if length is None or length[1] + length[0] > end:
                raise XdfError(f"{where}: sample {k}, channel {c} runs past the chunk's end")
            size, at = length
            if rows is not None:
                row.append(data[at:at + size].decode("utf-8", "replace"))
            at += size
        if rows is not None:
            rows.append(row)
    if at != end:
        raise XdfError(f"{where}: {end - at} bytes after its last sample")
    return last


def read(data: bytes, limits: XdfLimits | None = None, *, decode_strings: bool = True
         ) -> XdfFile:
    """The streams of an XDF file, time stamps as recorded (no clock synchronisation);
    `XdfError` for anything malformed or beyond `limits`. `decode_strings=False` keeps
    string streams' time stamps but not their text (values None)."""
    limits = limits or XdfLimits()
    pending, truncated, decoded = _walk(data, limits, decode_strings)
    out = []
    for stream in pending.values():
        stamps = np.empty(stream.samples, dtype=np.float64)
        values: NDArray[Any] | list[list[str]] | None
        values = np.empty((stream.samples, stream.info.channel_count),
                          dtype=stream.dtype.newbyteorder("=")) \
            if stream.dtype is not None else ([] if decode_strings else None)
        done, last = 0, 0.0
        quads = stream.chunks
        for i in range(0, len(quads), 4):
            chunk = (quads[i], quads[i + 1], quads[i + 2], quads[i + 3])
            n = chunk[3]
            if isinstance(values, np.ndarray):
                last = _decode_numeric(data, stream, stamps[done:done + n],
                                       values[done:done + n], last, chunk)
            else:
                last = _decode_strings(data, stream, stamps[done:done + n], values, last,
                                       chunk)
            done += n
        with np.errstate(invalid="ignore"):
            bad = np.flatnonzero(~(np.abs(stamps) < MAX_TIME))  # NaN included
        if bad.size:
            raise XdfError(f"stream {stream.info.stream_id} ({stream.info.name[:100]!r}): "
                           f"sample {int(bad[0])} has the time stamp {stamps[bad[0]]}, "
                           f"not a finite number of seconds within ±{MAX_TIME:g} s")
        out.append(XdfStream(stream.info, stamps, values,
                             np.frombuffer(stream.clock_times, dtype=np.float64).copy(),
                             np.frombuffer(stream.clock_values, dtype=np.float64).copy()))
    return XdfFile(out, truncated, decoded)
