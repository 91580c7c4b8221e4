"""Quality flags per EMG channel (and per trial window) and for the timestamps.

Flags describe; they never remove or alter data: flagged channels are kept and shown.
Every threshold is a named constant below with the reason for its value; they are
screening values meant to catch the failures a lab sees (a clipped amplifier, an
electrode off, mains pick-up, cable motion, a stream that drops samples), not a
verdict on the physiology.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.emg.normalisation import Window, check_window
from controller.emg.processing import MAINS_FREQUENCIES

CLIPPING = "clipping"
FLAT_LINE = "flat_line"
MAINS = "mains"
MOTION_ARTEFACT = "motion_artefact"
NON_FINITE = "non_finite"
DROPPED_SAMPLES = "dropped_samples"
RATE_MISMATCH = "rate_mismatch"
TIMESTAMPS_BACKWARDS = "timestamps_backwards"

# Clipping: a sample within this share of the range's span from a rail is "at" the rail.
# An ADC that saturates repeats its extreme code, so the tolerance only has to absorb
# the amplifier's own noise at the rail; 0.1 % of the span is far below the signal.
CLIPPING_TOLERANCE = 0.001
# With a known input range every sample at a rail is clipped. With none, the rails are
# the channel's own minimum and maximum, and a sample counts only in a run of this many
# consecutive samples at the same rail: a natural EMG peak at 1-4 kHz touches its
# extreme for one or two samples, a saturated amplifier stays there. (So without the
# range the count misses clipped excursions shorter than the run: it flags, it does not
# measure exactly.)
CLIPPING_MIN_RUN = 4
# Flat line (electrode off or channel dead): the RMS after DC removal below 0.1 uV.
# Surface EMG amplifiers' baseline noise is of the order of 1 uV RMS, so a channel
# measuring anything, even a muscle at rest, is well above it.
FLAT_LINE_RMS_V = 1e-7
# Mains: power density at 50 or 60 Hz (largest Welch bin within +-1 Hz) over the median
# density 5-15 Hz either side. 10 (10 dB) is well above the spectrum's own bin-to-bin
# scatter at the Welch resolution used (1 Hz, dozens of averaged segments in a trial).
MAINS_RATIO = 10.0
MAINS_PEAK_HALF_WIDTH_HZ = 1.0
MAINS_NEIGHBOUR_HZ = (5.0, 15.0)
# Motion artefact: share of the power between 0 and 20 Hz (DC excluded). Surface EMG
# has little power below the 20 Hz high-pass corner (De Luca et al. 2010 chose 20 Hz
# because movement artefacts concentrate below it); more than a quarter of the power
# there means movement of cables or skin dominates the channel.
MOTION_CUTOFF_HZ = 20.0
MOTION_SHARE = 0.25
# Dropped samples: an interval between timestamps longer than this many nominal periods
# is a gap. LSL timestamps jitter by a fraction of a period at 1-4 kHz, never by half.
GAP_PERIODS = 1.5
# Sampling rate vs timestamps: the rate the timestamps imply (gaps counted as missing
# samples) may differ from the nominal one by 1 %; amplifier clocks drift by parts per
# million, so more means a wrong nominal rate.
RATE_TOLERANCE = 0.01
# Welch segment length: 1 s (1 Hz resolution), shorter for short windows.
WELCH_SEGMENT_S = 1.0


@dataclass(frozen=True, slots=True)
class ChannelQuality:
    """One channel's measurements and the flags they raise."""

    channel: int
    n_samples: int
    non_finite: int
    rms_v: float
    clipped_samples: int
    mains_ratio: float
    mains_hz: int
    low_frequency_share: float
    flags: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {**asdict(self), "flags": list(self.flags)}


@dataclass(frozen=True, slots=True)
class TimingQuality:
    """What the timestamps say about the stream: gaps, the implied rate, restarts."""

    n_samples: int
    gaps: int
    dropped_samples: int
    backward_steps: int
    rate_from_timestamps_hz: float
    nominal_rate_hz: float
    flags: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {**asdict(self), "flags": list(self.flags)}


@dataclass(frozen=True, slots=True)
class QualityReport:
    """Per-channel quality and, when timestamps were given, the timing's."""

    channels: tuple[ChannelQuality, ...]
    timing: TimingQuality | None

    @property
    def flags(self) -> tuple[str, ...]:
        """Every flag raised anywhere, once each, in a stable order."""
        seen: dict[str, None] = {}
        for ch in self.channels:
            seen.update(dict.fromkeys(ch.flags))
        if self.timing is not None:
            seen.update(dict.fromkeys(self.timing.flags))
        return tuple(seen)

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {"channels": [c.to_dict() for c in self.channels],
                "timing": None if self.timing is None else self.timing.to_dict()}


def _runs_at(mask: NDArray[np.bool_], min_run: int) -> NDArray[np.int64]:
    """Per column of the (n, k) `mask`: its samples in runs of at least `min_run`
    consecutive True."""
    n, k = mask.shape
    if not mask.any():
        return np.zeros(k, dtype=np.int64)
    # The columns end to end, each between two False, so no run spans two columns.
    padded = np.zeros((k, n + 2), dtype=np.int8)
    padded[:, 1:-1] = mask.T
    edges = np.diff(padded.ravel())
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    lengths = stops - starts
    long = lengths >= min_run
    out = np.zeros(k, dtype=np.int64)
    np.add.at(out, starts[long] // (n + 2), lengths[long])
    return out


def clipped_counts(x: NDArray[Any], input_range: tuple[float, float] | None = None
                   ) -> NDArray[np.int64]:
    """`clipped_samples` of every column of an (n, k) array (float64) at once."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"expected an (n_samples, n_channels) array, got shape {arr.shape}")
    finite = np.isfinite(arr)
    usable = finite.any(axis=0)
    if input_range is not None:
        low, high = input_range
        span = high - low
        if span <= 0:
            return np.zeros(arr.shape[1], dtype=np.int64)
        tol = CLIPPING_TOLERANCE * span
        lows, highs = np.full(arr.shape[1], low + tol), np.full(arr.shape[1], high - tol)
    else:
        every = finite.all()
        low_v = (arr if every else np.where(finite, arr, np.inf)).min(axis=0, initial=np.inf)
        high_v = (arr if every else np.where(finite, arr, -np.inf)).max(axis=0,
                                                                          initial=-np.inf)
        with np.errstate(invalid="ignore"):  # columns with nothing finite: inf - inf
            spans = high_v - low_v
        usable &= spans > 0
        tols = CLIPPING_TOLERANCE * np.where(usable, spans, 0.0)
        lows, highs = low_v + tols, high_v - tols
    with np.errstate(invalid="ignore"):
        at_high = (arr >= highs) & usable
        at_low = (arr <= lows) & usable
    run = 1 if input_range is not None else CLIPPING_MIN_RUN
    return _runs_at(at_high, run) + _runs_at(at_low, run)


def clipped_samples(x: NDArray[Any], input_range: tuple[float, float] | None = None) -> int:
    """Samples of one channel at a rail of `input_range`, or in runs of CLIPPING_MIN_RUN
    at its own extremes when the range is not known (NaN ignored)."""
    return int(clipped_counts(np.asarray(x, dtype=np.float64)[:, None], input_range)[0])


def _centred(arr: NDArray[np.float64], finite: NDArray[np.bool_]
             ) -> Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]:
    """(columns, their finite samples minus their mean, one row per column) for every
    column with a finite sample: the wholly finite columns together in one pass, each
    other column alone. A row's arithmetic is the same either way (reductions along a
    contiguous row), so a channel's figures do not depend on its neighbours (tested)."""
    whole = finite.all(axis=0) & (arr.shape[0] > 0)
    cols = np.flatnonzero(whole)
    if cols.size:
        rows = np.ascontiguousarray(arr[:, cols].T)
        yield cols, rows - rows.mean(axis=1)[:, None]
    for c in np.flatnonzero(~whole & finite.any(axis=0)):
        good = arr[finite[:, c], c][None, :]
        yield np.array([c]), good - good.mean(axis=1)[:, None]


def dc_removed_rms(x: NDArray[Any]) -> NDArray[np.float64]:
    """Per column of an (n, k) array: the RMS of its finite samples about their mean
    (NaN for a column with none), the flat-line measure."""
    arr = np.asarray(x, dtype=np.float64)
    out = np.full(arr.shape[1], np.nan)
    for cols, centred in _centred(arr, np.isfinite(arr)):
        out[cols] = np.sqrt(np.mean(centred**2, axis=1))
    return out


def _spectrum(x: NDArray[np.float64], fs: float) -> tuple[NDArray[Any], NDArray[Any]]:
    """Welch densities of each row of `x` (rows are channels)."""
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy import signal

    nperseg = min(x.shape[-1], max(8, round(WELCH_SEGMENT_S * fs)))
    f, p = signal.welch(x, fs=fs, nperseg=nperseg, detrend="constant", axis=-1)
    return f, np.ascontiguousarray(p)


def mains_ratio(f: NDArray[Any], p: NDArray[Any], mains_hz: float) -> float:
    """Peak density near `mains_hz` over the median density of its neighbouring bands."""
    near = np.abs(f - mains_hz) <= MAINS_PEAK_HALF_WIDTH_HZ
    off = np.abs(f - mains_hz)
    beside = (off >= MAINS_NEIGHBOUR_HZ[0]) & (off <= MAINS_NEIGHBOUR_HZ[1])
    if not near.any() or not beside.any():
        return 0.0
    base = float(np.median(p[beside]))
    peak = float(p[near].max())
    if base <= 0:
        return float("inf") if peak > 0 else 0.0
    return peak / base


def _channels(raw: NDArray[np.float64], fs: float, numbers: Sequence[int],
              input_range: tuple[float, float] | None,
              mains_hz: int | None) -> tuple[ChannelQuality, ...]:
    """`channel_quality` of every column of `raw` (numbered `numbers`): the columns'
    reductions and spectra computed together, each channel's flags from its own."""
    n, k = raw.shape
    finite = np.isfinite(raw)
    non_finite = (~finite).sum(axis=0)
    good_n = finite.sum(axis=0)
    clipped = clipped_counts(raw, input_range)
    rms = np.zeros(k)
    spectral: dict[int, tuple[float, int, float]] = {}
    candidates = [mains_hz] if mains_hz is not None else list(MAINS_FREQUENCIES)
    for cols, centred in _centred(raw, finite):
        if centred.shape[1] < 2:
            continue
        rms[cols] = np.sqrt(np.mean(centred**2, axis=1))
        busy = rms[cols] >= FLAT_LINE_RMS_V
        if not busy.any():
            continue
        f, p = _spectrum(centred[busy], fs)
        for c, row in zip(cols[busy], p, strict=True):
            ratios = [(mains_ratio(f, row, m), m) for m in candidates if m < fs / 2]
            ratio, hz = max(ratios) if ratios else (0.0, 0)
            total = float(row[1:].sum())
            low = float(row[1:][f[1:] < MOTION_CUTOFF_HZ].sum())
            spectral[int(c)] = (float(ratio), int(hz), low / total if total > 0 else 0.0)
    out = []
    for c, number in enumerate(numbers):
        flags: list[str] = [NON_FINITE] if non_finite[c] else []
        nf = int(non_finite[c])
        if good_n[c] < 2:
            out.append(ChannelQuality(number, n, nf, 0.0, 0, 0.0, 0, 0.0,
                                      (*flags, FLAT_LINE)))
            continue
        if clipped[c]:
            flags.append(CLIPPING)
        r = float(rms[c])
        if r < FLAT_LINE_RMS_V:
            flags.append(FLAT_LINE)
            out.append(ChannelQuality(number, n, nf, r, int(clipped[c]), 0.0, 0, 0.0,
                                      tuple(flags)))
            continue
        ratio, hz, share = spectral[c]
        if ratio > MAINS_RATIO:
            flags.append(MAINS)
        if share > MOTION_SHARE:
            flags.append(MOTION_ARTEFACT)
        out.append(ChannelQuality(number, n, nf, r, int(clipped[c]), ratio, hz, share,
                                  tuple(flags)))
    return tuple(out)


def channel_quality(x: NDArray[Any], fs: float, channel: int = 0,
                    input_range: tuple[float, float] | None = None,
                    mains_hz: int | None = None) -> ChannelQuality:
    """Measure one channel (1-D raw samples, volts) and flag it.

    `mains_hz` None tests both 50 and 60 Hz and reports the worse.
    """
    raw = np.asarray(x, dtype=np.float64).reshape(-1, 1)
    return _channels(raw, fs, [channel], input_range, mains_hz)[0]


def timing_quality(timestamps: NDArray[Any], fs: float) -> TimingQuality:
    """Gaps, dropped samples, backward steps (a restart) and the implied sampling rate."""
    t = np.asarray(timestamps, dtype=np.float64)
    if t.ndim != 1:
        raise ValueError(f"timestamps must be 1-D, got shape {t.shape}")
    flags: list[str] = []
    if len(t) < 2:
        return TimingQuality(len(t), 0, 0, 0, float("nan"), float(fs), ())
    dt = np.diff(t)
    backward = int((dt < 0).sum())
    if backward:
        flags.append(TIMESTAMPS_BACKWARDS)
    period = 1.0 / fs
    spacing = dt[dt > 0]
    typical = float(np.median(spacing)) if spacing.size else period
    if not period / GAP_PERIODS <= typical <= GAP_PERIODS * period:
        # Stamped at another rate than the nominal (half of it, say): every step would
        # look like a gap. The stamps' own spacing is the period gaps are measured in;
        # the rate check below names the real problem (rate_mismatch).
        period = typical
    gap = dt > GAP_PERIODS * period
    missing = int(np.maximum(np.round(dt[gap] / period) - 1, 0).sum())
    if missing:
        flags.append(DROPPED_SAMPLES)
    forward = dt[dt > 0].sum()
    intervals = int((dt > 0).sum()) + missing
    rate = intervals / forward if forward > 0 else float("nan")
    if not np.isfinite(rate) or abs(rate - fs) > RATE_TOLERANCE * fs:
        flags.append(RATE_MISMATCH)
    return TimingQuality(len(t), int(gap.sum()), missing, backward, float(rate), float(fs),
                         tuple(flags))


def assess(raw: NDArray[Any], fs: float, timestamps: NDArray[Any] | None = None,
           input_range: tuple[float, float] | None = None,
           mains_hz: int | None = None) -> QualityReport:
    """Quality of a (n_samples, n_channels) recording; never raises on NaN/inf samples."""
    arr = np.asarray(raw, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"EMG must be a (n_samples, n_channels) array, got shape {arr.shape}")
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs}")
    if timestamps is not None and len(timestamps) != arr.shape[0]:
        raise ValueError(f"{len(timestamps)} timestamps for {arr.shape[0]} samples")
    channels = _channels(arr, fs, range(arr.shape[1]), input_range, mains_hz)
    timing = None if timestamps is None else timing_quality(np.asarray(timestamps), fs)
    return QualityReport(channels, timing)


def assess_windows(raw: NDArray[Any], fs: float, windows: Sequence[Window],
                   timestamps: NDArray[Any] | None = None,
                   input_range: tuple[float, float] | None = None,
                   mains_hz: int | None = None) -> list[QualityReport]:
    """`assess` for each trial window (sample indices, stop excluded)."""
    arr = np.asarray(raw, dtype=np.float64)
    out = []
    for w in windows:
        start, stop = check_window(w, arr.shape[0])
        ts = None if timestamps is None else np.asarray(timestamps)[start:stop]
        out.append(assess(arr[start:stop], fs, ts, input_range, mains_hz))
    return out
