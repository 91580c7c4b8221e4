"""A recording's quality flags, gathered block by block so an hour never sits in memory.

`controller.emg.quality` measures a window; a recording is assessed in blocks of
`BLOCK_S` seconds as it is written (live) or read (imports), and the summary keeps, per
channel label, in how many blocks each flag was raised, plus the timing's flags from
every finite timestamp (gaps, backward steps, the implied rate), carried across blocks.
Timestamps that are not finite are counted (`non_finite_timestamps`, flag
`timestamps_non_finite`) and left out of the timing checks, which go on over the rest.
Flags never drop or change data: they are stored with the recording and shown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.emg import quality

#: Seconds per assessed block: long enough for a 1 Hz Welch resolution and a flat-line
#: decision, short enough that a channel coming off for a few seconds shows.
BLOCK_S = 10.0
#: Extra flags of a live recording.
STREAM_LOST = "stream_lost"
STREAM_RESTARTED = "stream_restarted"
STOPPED_MID_TRIAL = "stopped_mid_trial"
#: Rows whose timestamp is NaN or infinite: stored, but with no place on the time axis
#: they are in no time window (envelopes, results, exports leave them out).
TIMESTAMPS_NON_FINITE = "timestamps_non_finite"
#: The server was killed mid-recording: what its file held was kept.
INTERRUPTED = "interrupted"


@dataclass
class QualitySummary:
    """Flags so far; feed it with `add`, read it with `to_dict`."""

    fs: float
    labels: list[str]
    mains_hz: int | None = None
    blocks: int = 0
    samples: int = 0
    non_finite: int = 0
    channel_flags: dict[str, dict[str, int]] = field(default_factory=dict)
    gaps: int = 0
    dropped_samples: int = 0
    backward_steps: int = 0
    non_finite_timestamps: int = 0
    extra: list[str] = field(default_factory=list)
    _span: float = 0.0
    _intervals: int = 0
    _last_t: float | None = None
    _last_row: int = 0
    _pending_t: list[NDArray[np.float64]] = field(default_factory=list)
    _pending_x: list[NDArray[Any]] = field(default_factory=list)
    _pending_n: int = 0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.fs) and 0 < self.fs <= 1e9):
            raise ValueError(f"sampling rate {self.fs!r} Hz cannot be assessed: it must be a "
                             "positive finite number of Hz")

    def add(self, timestamps: NDArray[Any] | None, samples: NDArray[Any]) -> None:
        """Take rows (as written); assesses every full block."""
        x = np.asarray(samples)
        t = (np.full(x.shape[0], np.nan) if timestamps is None
             else np.asarray(timestamps, dtype=np.float64))
        self._pending_t.append(t)
        self._pending_x.append(x)
        self._pending_n += x.shape[0]
        block = max(2, round(BLOCK_S * self.fs))
        while self._pending_n >= block:
            self._assess(block)

    def finish(self) -> None:
        """Assess what is left (a shorter last block)."""
        if self._pending_n:
            self._assess(self._pending_n)

    def flag(self, name: str) -> None:
        """A flag of the recording as a whole (the stream was lost, restarted ...)."""
        if name not in self.extra:
            self.extra.append(name)

    def _assess(self, n: int) -> None:
        t = np.concatenate(self._pending_t)
        x = np.concatenate(self._pending_x)
        bt, bx = t[:n], x[:n].astype(np.float64)
        self._pending_t, self._pending_x = [t[n:]], [x[n:]]
        self._pending_n = t.shape[0] - n
        report = quality.assess(bx, self.fs, mains_hz=self.mains_hz)
        self.blocks += 1
        self.samples += n
        for ch, label in zip(report.channels, self.labels, strict=True):
            self.non_finite += ch.non_finite
            for f in ch.flags:
                per = self.channel_flags.setdefault(label, {})
                per[f] = per.get(f, 0) + 1
        finite = np.isfinite(bt)
        self.non_finite_timestamps += int((~finite).sum())
        if finite.any():
            rows = np.arange(self.samples - n, self.samples)
            self._timing(bt[finite], rows[finite])

    def _timing(self, t: NDArray[np.float64], rows: NDArray[np.int64]) -> None:
        """Gaps and steps between finite stamps; `rows` are their row numbers, so a row
        between them whose stamp was not finite is a row, not a missing sample."""
        if self._last_t is not None:
            t = np.concatenate([[self._last_t], t])
            rows = np.concatenate([[self._last_row], rows])
        self._last_t, self._last_row = float(t[-1]), int(rows[-1])
        if t.size < 2:
            return
        dt = np.diff(t)
        steps = np.diff(rows)
        period = 1.0 / self.fs
        self.backward_steps += int((dt < 0).sum())
        gap = dt > (steps + quality.GAP_PERIODS - 1) * period
        self.gaps += int(gap.sum())
        missing = int(np.maximum(np.round(dt[gap] / period) - steps[gap], 0).sum())
        self.dropped_samples += missing
        self._span += float(dt[dt > 0].sum())
        self._intervals += int(steps[dt > 0].sum()) + missing

    @property
    def rate_from_timestamps_hz(self) -> float | None:
        """The rate the timestamps imply (gaps counted as missing samples)."""
        return self._intervals / self._span if self._span > 0 else None

    @property
    def flags(self) -> list[str]:
        """Every flag raised, once each."""
        out: dict[str, None] = {}
        for per in self.channel_flags.values():
            out.update(dict.fromkeys(per))
        if self.dropped_samples:
            out[quality.DROPPED_SAMPLES] = None
        if self.backward_steps:
            out[quality.TIMESTAMPS_BACKWARDS] = None
        if self.non_finite_timestamps:
            out[TIMESTAMPS_NON_FINITE] = None
        rate = self.rate_from_timestamps_hz
        if rate is not None and abs(rate - self.fs) > quality.RATE_TOLERANCE * self.fs:
            out[quality.RATE_MISMATCH] = None
        out.update(dict.fromkeys(self.extra))
        return list(out)

    def to_dict(self) -> dict[str, Any]:
        """Stored with the recording (`EmgRecording.quality`)."""
        rate = self.rate_from_timestamps_hz
        return {"flags": self.flags, "block_s": BLOCK_S, "blocks": self.blocks,
                "samples": self.samples, "non_finite_samples": self.non_finite,
                "channels": self.channel_flags, "gaps": self.gaps,
                "dropped_samples": self.dropped_samples,
                "backward_steps": self.backward_steps,
                "non_finite_timestamps": self.non_finite_timestamps,
                "excluded_from_time_windows": (
                    f"{self.non_finite_timestamps} rows with a non-finite timestamp are "
                    "stored but in no time window" if self.non_finite_timestamps
                    else None),
                "rate_from_timestamps_hz": rate, "nominal_rate_hz": self.fs}
