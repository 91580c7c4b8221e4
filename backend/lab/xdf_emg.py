"""The EMG stream of a LabRecorder XDF file, imported into the session's EMG store.

The file is read by the bounded reader in its child process (`backend.lab.xdf_child`),
which puts every stream on the recording computer's clock with the clock offsets
LabRecorder stored and writes a numeric EMG stream's time stamps and samples to `.npy`
files; this module reads those a block at a time, so the server never holds the
recording whole. ExoStudy's tick stream in the same file gives the difference between
that clock and the session's (`backend.lab.xdf_import.clock_shift`), as for the
attachment's summary; the recording keeps the file's stamps and that difference as its
`time_offset_s`.

Checked before anything is stored: the file has one EMG stream (or the request names
it), numeric, with a regular nominal rate, channel units that are voltages, and labels
that match the study's montage (`ChannelMismatchError` listing unmatched, missing and
expected labels). NaN or infinite samples, a rate that disagrees with the stamps, gaps
and steps backwards are stored as they are and flagged in the recording's quality.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from sqlalchemy import Engine
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.emg import EmgRecording
from backend.emg import recordings
from backend.emg.recordings import Block
from backend.lab import xdf_child, xdf_import
from backend.lab.xdf_child import ParsedStream

#: Rows read from the child's files at a time (5 s at 2 kHz).
BLOCK_ROWS = 10_000
#: Flag of a recording whose file held no ExoStudy tick stream to align it with.
ALIGNMENT_ASSUMED = "alignment_assumed"


def _describe(s: ParsedStream) -> str:
    return f"{s.stream_id} {s.name!r} (type {s.type!r})"


def choose(streams: list[ParsedStream], stream: str | None) -> ParsedStream:
    """The EMG stream to import: the one named (by name or stream id), or the file's
    only stream of type EMG; ValueError listing the file's streams otherwise."""
    emg = [s for s in streams if s.type.strip().casefold() == xdf_child.EMG_STREAM_TYPE]
    listing = ", ".join(_describe(s) for s in streams)
    if stream:
        named = [s for s in streams if stream in (s.name, str(s.stream_id))]
        if not named:
            raise ValueError(f"the XDF file has no stream {stream!r}; its streams: {listing}")
        if named[0] not in emg:
            raise ValueError(f"stream {_describe(named[0])} is not of type EMG")
        emg = named[:1]
    if not emg:
        raise ValueError(f"the XDF file has no stream of type EMG; its streams: {listing}")
    if len(emg) > 1:
        raise ValueError("the XDF file has several EMG streams ("
                         + ", ".join(_describe(s) for s in emg) + "): name one as `stream`")
    chosen = emg[0]
    if chosen.emg is None:
        raise ValueError(f"stream {_describe(chosen)} holds text or no samples, not EMG")
    if not chosen.nominal_srate > 0:
        raise ValueError(f"stream {_describe(chosen)} has no regular sampling rate (nominal "
                         f"{chosen.nominal_srate:g} Hz); EMG needs one")
    if chosen.labelled_channels != chosen.channel_count:
        raise ValueError(f"stream {_describe(chosen)} labels {chosen.labelled_channels} of its "
                         f"{chosen.channel_count} channels; the montage maps channels by "
                         "label")
    return chosen


def import_file(engine: Engine, db: Session, settings: Settings, session_id: int,
                data: bytes, filename: str, stream: str | None, ignore_labels: list[str],
                user_id: int | None = None, mains_hz: int | None = None) -> EmgRecording:
    """Store the XDF file's EMG stream as a recording of the session; ValueError (a 4xx)
    for a file, a stream or a montage that does not fit. Nothing is stored on error."""
    montage = recordings.session_montage(db, session_id)
    with xdf_child.parsed(data, xdf_import.limits(settings), settings.xdf_work_dir,
                          settings.xdf_parse_seconds) as streams:
        s = choose(streams, stream)
        assert s.emg is not None
        labels, units = xdf_child.channel_labels(s)
        cols = recordings.map_channels(montage, labels, ignore_labels)
        units += [""] * (s.channel_count - len(units))
        factors = []
        for i in cols:
            try:
                factors.append(recordings.volts_per_unit(units[i]))
            except ValueError as exc:
                raise ValueError(f"stream {_describe(s)}, channel {labels[i]!r}: "
                                 f"{exc}") from exc
        shift = xdf_import.clock_shift(engine, db, session_id, streams)
        if shift is None:
            how = ("XDF: no ExoStudy tick stream of this session in the file; the file's "
                   "clock (after its clock offsets) taken as this server's LSL clock")
        else:
            how = (f"XDF: stream {s.stream_id} on the recording computer's clock through "
                   f"the file's clock offsets; that clock is {shift:+.6f} s from the "
                   "session's, found from ExoStudy's tick stream in the file")
        t_all = np.load(s.emg[0], mmap_mode="r", allow_pickle=False)
        x_all = np.load(s.emg[1], mmap_mode="r", allow_pickle=False)
        if x_all.ndim != 2 or x_all.shape[0] != t_all.shape[0]:
            raise ValueError(f"stream {_describe(s)}: {t_all.shape[0]} time stamps for "
                             f"samples of shape {x_all.shape}")
        scale = np.asarray(factors)
        index = np.asarray(cols)

        def blocks() -> Iterator[Block]:
            for lo in range(0, t_all.shape[0], BLOCK_ROWS):
                t = np.asarray(t_all[lo:lo + BLOCK_ROWS], dtype=np.float64)
                x = np.asarray(x_all[lo:lo + BLOCK_ROWS][:, index], dtype=np.float64)
                yield t, x * scale

        writer_flags = [] if shift is not None else [ALIGNMENT_ASSUMED]
        return recordings.store_blocks(
            db, settings, session_id, montage, "xdf", s.nominal_srate, blocks(),
            -(shift or 0.0), how, filename, user_id, mains_hz, flags=writer_flags)
