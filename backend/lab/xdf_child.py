"""An uploaded XDF file, read in a child process with a memory and a time ceiling.

The server does not decode an upload itself. It writes the file into a private folder
under its data folder (`xdf_work_dir`: folders 0700, files 0600; not /tmp, which is
often memory), and a child process reads it with the bounded reader
(`backend/lab/xdf_reader.py`), moves every stream onto the recording computer's clock
(`backend/lab/xdf_clock.py`), checks ExoStudy's own tick stream, and writes back a
small summary (JSON, about a hundred bytes a stream plus its channel labels) and the
tick stream's (time, seq) columns as an `.npy` file that the server reads from disk a
block at a time. The summary keeps the first `summary_channels` labels of each stream,
cut to `MAX_LABEL` characters, and their count: a file of 96 headers of 65,536
labelled channels brought 6 million labels back into the server and stored 25 MB of
summary (issue 28). An EMG stream's labels and units, which the import needs whole,
go to a file of their own. So what a file decodes to stays in the child, whose address space is
limited (`RLIMIT_AS`), and goes away with it: an 18 MB string stream no longer comes
back into the server as millions of Python strings (issue 28).

A child that runs out of memory, runs past `xdf_parse_seconds`, or stops for any other
reason refuses the file (`XdfError`, a 422 at the API); nothing of a partial read is
used. The folder is removed when the caller is done with it.
"""

from __future__ import annotations

import json
import logging
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from backend.lab import xdf_clock, xdf_reader
from backend.lab.xdf_reader import XdfError, XdfFile, XdfLimits, XdfStream
from controller.private_files import create_private_file, make_private_dir, write_private

log = logging.getLogger(__name__)

#: The stream type of ExoStudy's tick outlet (backend/lab/lsl_outlets.py).
TICK_STREAM_TYPE = "ExoskeletonTicks"
#: The tick channel that numbers samples; the import matches it with stored ticks.
SEQ_CHANNEL = "seq"
#: The stream type of an EMG amplifier's stream (case does not matter).
EMG_STREAM_TYPE = "emg"
#: Largest sample number a tick stream may carry: every whole number up to it is exact
#: in a double, which is what the LSL stream sends.
MAX_SEQ = 2**53
#: Characters kept of a stream's name, type and source id in the summary.
MAX_TEXT = 200
#: Characters kept of a channel label in the summary.
MAX_LABEL = 64
#: Channel labels of a stream the summary keeps unless told otherwise (the server's
#: xdf_summary_channels).
SUMMARY_CHANNELS = 64
#: Address space of the child beyond what it decodes: the interpreter with numpy (about
#: 150 MB virtual, measured with VmPeak) and headroom for the XML parser.
CHILD_BASE_BYTES = 512 * 1024**2

UPLOAD, SUMMARY, ERROR = "upload.xdf", "summary.json", "error.txt"
#: Exit statuses of the child besides 0.
_REFUSED, _OUT_OF_MEMORY = 2, 3
_ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class ParsedStream:
    """One stream of a read file, on the recording computer's clock."""

    stream_id: int
    name: str
    type: str
    source_id: str
    channel_count: int
    channel_format: str
    nominal_srate: float
    #: The first labels of `desc/channels` (at most the summary's count, each cut to
    #: MAX_LABEL characters).
    channels: list[str]
    #: How many channels the header labels (at most `channel_count`).
    labelled_channels: int
    samples: int
    first_time: float | None
    last_time: float | None
    #: ExoStudy tick streams only: the `.npy` file of (time, seq) rows, float64.
    ticks: Path | None = None
    #: Numeric streams of type EMG only: the `.npy` files of the time stamps (float64,
    #: on the recording computer's clock) and of the samples (as recorded), which the
    #: server reads a block at a time (`backend.lab.xdf_emg`), and the JSON file of all
    #: its channel labels and units (`channel_labels`).
    emg: tuple[Path, Path, Path] | None = None


def address_space(limits: XdfLimits, file_bytes: int) -> int:
    """Bytes of address space the child may use for a file of `file_bytes`: the base,
    the file, and twice the decoded limit (a stream's time stamps are copied once when
    its clock is synchronised)."""
    return CHILD_BASE_BYTES + file_bytes + 2 * limits.max_decoded_bytes


def _clip(text: str) -> str:
    return text[:MAX_TEXT]


def channel_labels(stream: ParsedStream) -> tuple[list[str], list[str]]:
    """All channel labels of an EMG stream and their units ("" where the header gives
    none), as many as it declares channels at most; read from the child's file, whose
    size the header limit bounds."""
    if stream.emg is None:
        raise ValueError(f"stream {stream.stream_id} is not a numeric EMG stream")
    found = json.loads(stream.emg[2].read_text())
    return [str(x) for x in found["labels"]], [str(x) for x in found["units"]]


def _tick_columns(stream: XdfStream, stamps: np.ndarray[Any, np.dtype[np.float64]]
                  ) -> np.ndarray[Any, np.dtype[np.float64]]:
    """(time, seq) rows of an ExoStudy tick stream, every field checked."""
    info = stream.info
    where = f"stream {info.stream_id} ({_clip(info.name)!r}, type {TICK_STREAM_TYPE})"
    if info.channel_format == "string" or not isinstance(stream.values, np.ndarray):
        raise XdfError(f"{where}: its channels are text, so its {SEQ_CHANNEL} channel "
                       "holds strings, not sample numbers")
    if len(info.labels) != info.channel_count:
        raise XdfError(f"{where}: declares {info.channel_count} channels but labels "
                       f"{len(info.labels)}")
    if info.labels.count(SEQ_CHANNEL) != 1:
        raise XdfError(f"{where}: needs exactly one channel labelled {SEQ_CHANNEL!r}, "
                       f"has {info.labels.count(SEQ_CHANNEL)}")
    seq = stream.values[:, info.labels.index(SEQ_CHANNEL)].astype(np.float64)
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(seq) | (seq < 0) | (seq > MAX_SEQ) | (seq != np.floor(seq))
    if bad.any():
        k = int(np.argmax(bad))
        raise XdfError(f"{where}: sample {k} has {SEQ_CHANNEL} {float(seq[k])!r}, not a whole "
                       f"sample number from 0 to {MAX_SEQ}")
    return np.column_stack((stamps, seq))


def summarize(parsed: XdfFile, folder: Path, summary_channels: int = SUMMARY_CHANNELS
              ) -> list[dict[str, Any]]:
    """The summary of every stream (tick columns written into `folder`), its clock
    synchronised, with at most `summary_channels` labels a stream; XdfError names a
    field that cannot be used."""
    out = []
    for stream in parsed.streams:
        info = stream.info
        stamps = xdf_clock.synchronize(stream.time_stamps, stream.clock_times,
                                       stream.clock_values)
        with np.errstate(invalid="ignore"):
            outside = ~(np.abs(stamps) < xdf_reader.MAX_TIME)
        if outside.any():
            raise XdfError(f"stream {info.stream_id} ({_clip(info.name)!r}): its clock "
                           "offsets move its time stamps out of the range "
                           f"±{xdf_reader.MAX_TIME:g} s")
        ticks = None
        if info.type == TICK_STREAM_TYPE:
            cols = _tick_columns(stream, stamps)
            ticks = folder / f"ticks-{info.stream_id}.npy"
            if not create_private_file(ticks):
                raise XdfError(f"stream {info.stream_id}: a second tick stream of that id")
            with ticks.open("wb") as f:
                np.save(f, cols, allow_pickle=False)
        labels = info.labels[:info.channel_count]
        emg = None
        if (info.type.strip().casefold() == EMG_STREAM_TYPE
                and isinstance(stream.values, np.ndarray) and stamps.size):
            emg = [f"emg-{info.stream_id}-{part}" for part in ("t.npy", "x.npy",
                                                                "labels.json")]
            for name in emg:
                if not create_private_file(folder / name):
                    raise XdfError(f"stream {info.stream_id}: a second EMG stream of that id")
            for name, arr in zip(emg[:2], (stamps, stream.values), strict=True):
                with (folder / name).open("wb") as f:
                    np.save(f, arr, allow_pickle=False)
            write_private(folder / emg[2], json.dumps(
                {"labels": labels, "units": info.units[:len(labels)]}).encode())
        out.append({
            "stream_id": info.stream_id, "name": _clip(info.name), "type": _clip(info.type),
            "source_id": _clip(info.source_id), "channel_count": info.channel_count,
            "channel_format": info.channel_format, "nominal_srate": info.nominal_srate,
            "channels": [label[:MAX_LABEL] for label in labels[:summary_channels]],
            "labelled_channels": len(labels), "samples": int(stamps.size),
            "first_time": float(stamps[0]) if stamps.size else None,
            "last_time": float(stamps[-1]) if stamps.size else None,
            "ticks": None if ticks is None else ticks.name, "emg": emg})
    return out


def _refuse_constant(name: str) -> float:
    raise ValueError(f"the reader's summary holds {name}")


def _summary(folder: Path) -> list[ParsedStream]:
    """The child's summary, read back with its types checked."""
    rows = json.loads((folder / SUMMARY).read_text(), parse_constant=_refuse_constant)
    out = []
    for row in rows:
        ticks, emg = row.pop("ticks"), row.pop("emg")
        stream = ParsedStream(**row, ticks=None if ticks is None else folder / ticks,
                              emg=None if emg is None else (folder / emg[0], folder / emg[1],
                                                            folder / emg[2]))
        for value in (stream.nominal_srate, stream.first_time, stream.last_time):
            if value is not None and not math.isfinite(value):
                raise ValueError(f"the reader's summary holds {value}")
        out.append(stream)
    return out


def _command(folder: Path, limits: XdfLimits, space: int, timeout_s: float,
             summary_channels: int) -> list[str]:
    """The child's command line."""
    return [sys.executable, "-m", "backend.lab.xdf_child", str(folder),
            json.dumps(asdict(limits)), str(space), str(timeout_s), str(summary_channels)]


def _run(folder: Path, limits: XdfLimits, timeout_s: float, file_bytes: int,
         summary_channels: int) -> None:
    """Run the child on `folder`; XdfError for every way it can fail."""
    space = address_space(limits, file_bytes)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(_ROOT),
                                                       os.environ.get("PYTHONPATH")]))}
    command = _command(folder, limits, space, timeout_s, summary_channels)
    try:
        done = subprocess.run(command, env=env, stdin=subprocess.DEVNULL,
                              capture_output=True, text=True, timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired as exc:
        raise XdfError(f"reading the file took longer than {timeout_s:g} s (the server's "
                       "xdf_parse_seconds); it was stopped and nothing of it kept") from exc
    if done.returncode == 0:
        return
    if done.returncode == _REFUSED and (folder / ERROR).is_file():
        raise XdfError((folder / ERROR).read_text(errors="replace"))
    if done.returncode == _OUT_OF_MEMORY or "MemoryError" in done.stderr:
        raise XdfError(f"reading the file needs more than {space} bytes of memory "
                       "(the server's xdf_max_decoded_bytes sets the ceiling)")
    if done.returncode < 0:
        name = signal.Signals(-done.returncode).name
        raise XdfError(f"the XDF reader was stopped ({name}) before it finished; "
                       "nothing of the file was kept")
    log.error("the XDF reader failed (exit %s): %s", done.returncode, done.stderr[-4000:])
    last = (done.stderr.strip().splitlines() or ["no message"])[-1]
    raise XdfError(f"the XDF file cannot be read: {last[:300]}")


@contextmanager
def parsed(data: bytes, limits: XdfLimits, work_dir: Path, timeout_s: float,
           summary_channels: int = SUMMARY_CHANNELS) -> Iterator[list[ParsedStream]]:
    """The summary of the XDF file `data` (at most `summary_channels` labels a stream),
    read by a child process in a private folder under `work_dir` that is removed when
    the block ends; XdfError names the problem."""
    xdf_reader.require_magic(data)  # no process for what is plainly not XDF
    make_private_dir(work_dir)
    folder = Path(tempfile.mkdtemp(prefix="upload-", dir=work_dir))  # mode 0700
    try:
        write_private(folder / UPLOAD, data)
        _run(folder, limits, timeout_s, len(data), summary_channels)
        yield _summary(folder)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _child(folder: Path, limits: XdfLimits, space: int, timeout_s: float,
           summary_channels: int) -> int:
    resource.setrlimit(resource.RLIMIT_AS, (space, space))
    # A second stop should the server die and leave the child behind.
    cpu = math.ceil(timeout_s) + 1
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    try:
        read = xdf_reader.read((folder / UPLOAD).read_bytes(), limits, decode_strings=False)
        summary = summarize(read, folder, summary_channels)
        write_private(folder / SUMMARY, json.dumps(summary, allow_nan=False).encode())
    except XdfError as exc:
        write_private(folder / ERROR, str(exc).encode()[:4000])
        return _REFUSED
    except MemoryError:
        return _OUT_OF_MEMORY
    return 0


if __name__ == "__main__":
    sys.exit(_child(Path(sys.argv[1]), XdfLimits(**json.loads(sys.argv[2])),
                    int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])))
