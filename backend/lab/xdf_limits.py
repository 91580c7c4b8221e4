"""What an XDF file may make the server allocate, checked before pyxdf reads it.

pyxdf allocates what a file declares: a Samples chunk's sample count becomes
`np.zeros((count, channels))` (or, for strings, a list of `count` lists of `channels`
entries) before a single sample is read, and a stream header's `channel_count` sizes
every sample. A 573-byte file declaring 30 million samples took 2.5 GB, and one
declaring 250 million channels 4.5 GB (issue 23). This module walks the chunk
structure itself (XDF 1.0: `XDF:`, then chunks of [length-byte count 1/4/8][length]
[tag u16][content]; a Samples chunk holds the stream id and a variable-length sample
count) and refuses a file whose declared sizes do not fit in its own bytes, or whose
decoded size would pass a stated limit, before anything is allocated.

A file cut short (LabRecorder killed mid-write) is not refused: its last, incomplete
chunk is left out of what pyxdf reads (the stored file stays whole).
"""

from __future__ import annotations

import os
import pickle
import resource
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

#: Bytes of one value per channel format (strings: at least a 1-byte length field and a
#: 1-byte length, for the empty string).
VALUE_BYTES = {"double64": 8, "float32": 4, "int64": 8, "int32": 4, "int16": 2, "int8": 1,
               "string": 2}
#: Most channels a stream may declare: high-density EMG or EEG has a few hundred, a
#: motion capture stream of 100 markers 300; 65 536 leaves room for anything real.
MAX_CHANNELS = 65_536
#: Largest decoded size (bytes) pyxdf may build from one file: an assumption for a lab
#: PC with 8 GB or more, where one upload may take an eighth of it. A 512 MB file of
#: double samples decodes to about 1 GB, so this refuses no real recording.
MAX_DECODED_BYTES = 1024**3
#: Python's cost of one string value (a str object and its list slot), beyond its text.
_STRING_OVERHEAD = 60
#: A list per string sample: header and one slot per channel.
_LIST_OVERHEAD = 56


class XdfRefusedError(ValueError):
    """The file declares more than it holds or than the server will decode."""


@dataclass
class _Stream:
    channels: int
    fmt: str


@dataclass
class XdfPlan:
    """What a check found: the bytes pyxdf should read and the estimated decoded size."""

    readable_bytes: int
    decoded_bytes: int
    streams: dict[int, _Stream] = field(default_factory=dict)
    truncated: bool = False


def _varlen(data: bytes, pos: int) -> tuple[int, int] | None:
    """(value, position after it) of a variable-length integer, None if cut short or
    malformed."""
    if pos >= len(data):
        return None
    width = data[pos]
    fmt = {1: "<B", 4: "<I", 8: "<Q"}.get(width)
    if fmt is None or pos + 1 + width > len(data):
        return None
    return struct.unpack_from(fmt, data, pos + 1)[0], pos + 1 + width


def _header(content: bytes, where: str) -> _Stream:
    try:
        root = ElementTree.fromstring(content.decode("utf-8", "replace"))
    except ElementTree.ParseError as exc:
        raise XdfRefusedError(f"{where}: the stream header is not XML ({exc})") from exc
    count_text = (root.findtext("channel_count") or "").strip()
    fmt = (root.findtext("channel_format") or "").strip()
    if not count_text.isdigit() or not 1 <= int(count_text) <= MAX_CHANNELS:
        raise XdfRefusedError(f"{where}: channel_count {count_text[:20]!r} must be a whole "
                         f"number from 1 to {MAX_CHANNELS}")
    if fmt not in VALUE_BYTES:
        raise XdfRefusedError(f"{where}: channel_format {fmt[:20]!r} is not one of "
                         f"{sorted(VALUE_BYTES)}")
    return _Stream(int(count_text), fmt)


def _decoded(stream: _Stream, samples: int) -> int:
    """Bytes pyxdf holds for `samples` samples (time stamps included), twice for the
    numeric arrays it concatenates at the end."""
    if stream.fmt == "string":
        return samples * (8 + _LIST_OVERHEAD + 8 * stream.channels
                          + _STRING_OVERHEAD * stream.channels)
    return 2 * samples * (8 + VALUE_BYTES[stream.fmt] * stream.channels)


def check(data: bytes, max_decoded_bytes: int = MAX_DECODED_BYTES) -> XdfPlan:
    """Walk the chunks of an XDF file and refuse (`XdfRefusedError`, naming the byte offset)
    a stream header or Samples chunk that declares more than the file holds, or a file
    whose decoded size would pass `max_decoded_bytes`."""
    if not data.startswith(b"XDF:"):
        raise XdfRefusedError("not an XDF file (it does not start with 'XDF:')")
    plan = XdfPlan(readable_bytes=4, decoded_bytes=0)
    pos = 4
    while pos < len(data):
        length = _varlen(data, pos)
        if length is None or length[0] < 2 or length[1] + length[0] > len(data):
            # A length field that is cut short or points past the end: the file ends
            # here for pyxdf (a recording stopped mid-chunk).
            plan.truncated = True
            break
        size, start = length
        end = start + size
        tag = struct.unpack_from("<H", data, start)[0]
        content = data[start + 2:end]
        where = f"chunk at byte {pos}"
        if tag in (2, 3, 4, 6) and len(content) < 4:
            raise XdfRefusedError(f"{where}: too short for its stream id")
        if tag == 2:
            sid = struct.unpack_from("<I", content)[0]
            plan.streams[sid] = _header(content[4:], f"{where} (stream {sid})")
        elif tag == 3:
            sid = struct.unpack_from("<I", content)[0]
            stream = plan.streams.get(sid)
            count = _varlen(content, 4)
            if stream is None or count is None:
                # pyxdf skips such a chunk without allocating for it.
                pos = end
                plan.readable_bytes = end
                continue
            samples, first = count
            room = len(content) - first
            least = samples * (1 + VALUE_BYTES[stream.fmt] * stream.channels)
            if least > room:
                raise XdfRefusedError(
                    f"{where} (stream {sid}): declares {samples} samples of "
                    f"{stream.channels} {stream.fmt} channels, which need at least {least} "
                    f"bytes, but the chunk holds {room}")
            plan.decoded_bytes += _decoded(stream, samples)
            if plan.decoded_bytes > max_decoded_bytes:
                raise XdfRefusedError(
                    f"{where} (stream {sid}): the file would decode to more than "
                    f"{max_decoded_bytes} bytes in memory")
        pos = end
        plan.readable_bytes = end
    return plan


# --- The second layer: pyxdf in a child process with a memory ceiling ---------------------
#: Address space (bytes) the parsing process may use: the interpreter with numpy and
#: pyxdf (about 140 MB virtual, measured with VmPeak), the decoded data, and pyxdf's
#: copies when it concatenates. Should the estimate above ever be wrong, the child
#: fails with MemoryError instead of the server growing.
CHILD_ADDRESS_SPACE = 512 * 1024**2 + 2 * MAX_DECODED_BYTES
#: Longest a parse may take (a 64 MB file takes seconds; an assumption with a wide
#: margin for a loaded machine).
_CHILD_TIMEOUT_S = 600
#: Exit status of a child that ran out of its allowed memory.
_OUT_OF_MEMORY = 3


def load(data: bytes, address_space: int = CHILD_ADDRESS_SPACE) -> list[dict[str, Any]]:
    """`pyxdf.load_xdf` of `data` (clock synchronisation on, no de-jittering), run in a
    child process limited to `address_space` bytes; ValueError names the problem."""
    with tempfile.TemporaryDirectory(prefix="exostudy-xdf-") as folder:
        source = Path(folder) / "in.xdf"
        target = Path(folder) / "out.pickle"
        source.write_bytes(data)
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "PYTHONPATH": os.pathsep.join(filter(None, [str(_ROOT),
                                                           os.environ.get("PYTHONPATH")]))}
        try:
            done = subprocess.run(
                [sys.executable, "-m", "backend.lab.xdf_limits", str(source), str(target),
                 str(address_space)], env=env, capture_output=True, text=True,
                timeout=_CHILD_TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired as exc:
            raise ValueError(f"reading the XDF file took longer than {_CHILD_TIMEOUT_S} s"
                             ) from exc
        if done.returncode == _OUT_OF_MEMORY:
            raise XdfRefusedError(f"reading the file needs more than {address_space} bytes of "
                             "memory")
        if done.returncode != 0:
            last = (done.stderr.strip().splitlines() or ["no message"])[-1]
            raise ValueError(f"the XDF file cannot be read: {last[:300]}")
        with target.open("rb") as f:
            streams: list[dict[str, Any]] = pickle.load(f)  # written by our own child
    return streams


def _child(source: str, target: str, address_space: int) -> int:
    resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    try:
        import pyxdf

        streams, _header = pyxdf.load_xdf(source, synchronize_clocks=True,
                                          dejitter_timestamps=False)
        with open(target, "wb") as f:
            pickle.dump(list(streams), f, protocol=pickle.HIGHEST_PROTOCOL)
    except MemoryError:
        print("out of memory", file=sys.stderr)
        return _OUT_OF_MEMORY
    return 0


_ROOT = Path(__file__).resolve().parents[2]

if __name__ == "__main__":
    sys.exit(_child(sys.argv[1], sys.argv[2], int(sys.argv[3])))
