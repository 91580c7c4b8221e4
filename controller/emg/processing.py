"""The standard EMG amplitude chain: settings, offline (zero-phase) and live (causal).

Offline, `process(raw, fs, settings)` runs, per channel:

1. DC removal: subtract the channel's mean (in float64, before any narrowing).
2. Band-pass: Butterworth of order `bandpass_order` (scipy's N: each edge rolls off
   like an N-th order low/high-pass), 20-450 Hz by default (30 Hz high-pass for trunk
   muscles near the heart: `EmgProcessing.trunk()`), applied forward and backward
   (`sosfiltfilt`), so zero phase and a squared magnitude response.
3. Notch at the mains frequency (None, 50 or 60 Hz; quality factor `notch_q`), also
   zero phase.
4. Full-wave rectification (absolute value).
5. Envelope: Butterworth low-pass, `envelope_hz` (6 Hz by default), zero phase.

Normalisation (`normalisation.py`) is a separate step because it needs references from
other windows (MVC trials, the task); its method and moving-average window are settings
here, so one record holds every parameter of a study's analysis.

Precision: the filters run in float32 by default (`precision="float32"`); against
float64 the envelope differs by less than 0.1 % of its mean (tested).
`precision="float64"` is exact to scipy's double precision. The envelope is returned as
float64 either way. The filtering is `zero_phase.zero_phase`: scipy's `sosfiltfilt`
per channel, to rounding, computed for 16 channels side by side in place in the output,
so both precisions take about the same time and no per-channel copies are made.

Live, `EnvelopeStream` runs the same filters causally (`sosfilt` with state, computed
by `zero_phase.CausalEnvelope` for all channels in one pass): it lags and its ripple
differs from the zero-phase envelope, but on a steady signal it settles to the same
level (tested); it is for the console's strip, never for results.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, fields
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from controller.emg.zero_phase import LANES, CausalEnvelope, zero_phase

FloatArray = NDArray[np.float64]

NormalisationMethod = Literal["mvc", "task_peak", "task_mean", "none"]
NORMALISATION_METHODS: tuple[str, ...] = get_args(NormalisationMethod)
Precision = Literal["float32", "float64"]
PRECISIONS: tuple[str, ...] = get_args(Precision)
MAINS_FREQUENCIES = (50, 60)

# The band-pass's upper edge is clipped to this share of the Nyquist frequency when a
# low sampling rate puts it above: a Butterworth edge at Nyquist itself is undefined.
NYQUIST_MARGIN = 0.95
# Below this sampling rate the chain refuses: with the default 20 Hz high-pass, a clipped
# upper edge under 100 Hz would keep too little of the sEMG spectrum (most of its power
# lies between 20 and 150 Hz) to call the result an amplitude estimate.
MIN_UPPER_EDGE_HZ = 100.0
SETTINGS_VERSION = 1
# Records shorter than this (about a minute at 2 kHz) are filtered on one thread.
THREADED_SAMPLES = 100_000


#: The allowed range of each numeric setting, inclusive, with the reason for each bound.
#: Outside them a filter is numerically degenerate (a notch with Q near zero or a 1e-300
#: Hz low-pass gives NaN coefficients) or no longer an EMG amplitude estimate.
RANGES: dict[str, tuple[float, float, str]] = {
    "highpass_hz": (1.0, 250.0, "below 1 Hz the band-pass keeps movement artefact and its "
                    "design is ill-conditioned at kHz rates; above 250 Hz it removes most "
                    "of the sEMG power (20-150 Hz)"),
    "lowpass_hz": (50.0, 10000.0, "below 50 Hz too little of the sEMG spectrum is kept; "
                   "above 10 kHz no surface EMG amplifier has content (the edge is clipped "
                   "to 95 % of Nyquist anyway)"),
    "notch_q": (1.0, 200.0, "below 1 the notch is wider than the mains frequency and "
                "removes the EMG band; above 200 it is narrower than the mains drift"),
    "envelope_hz": (0.5, 50.0, "below 0.5 Hz the envelope smears over a whole lift; above "
                    "50 Hz it no longer smooths the rectified signal"),
    "mvc_window_s": (0.05, 5.0, "shorter than 50 ms is a single burst, longer than 5 s "
                     "exceeds an MVC contraction"),
}


def allowed_ranges() -> str:
    """The ranges in words, for error messages and the API's schema."""
    return "; ".join(f"{k} {lo:g} to {hi:g} ({why})" for k, (lo, hi, why) in RANGES.items())


class EmgSettingsError(ValueError):
    """A processing setting, or its combination with a sampling rate, is not usable."""


@dataclass(frozen=True, slots=True)
class EmgProcessing:
    """Every parameter of the amplitude chain, saved with a study's analysis settings
    and written into every export (`to_dict`)."""

    remove_dc: bool = True
    highpass_hz: float = 20.0
    lowpass_hz: float = 450.0
    bandpass_order: int = 4
    notch_hz: int | None = None
    notch_q: float = 30.0
    rectification: Literal["full_wave"] = "full_wave"
    envelope_hz: float = 6.0
    envelope_order: int = 4
    normalisation: NormalisationMethod = "mvc"
    mvc_window_s: float = 0.5
    precision: Precision = "float32"

    def __post_init__(self) -> None:
        problems = []
        if not isinstance(self.remove_dc, bool):
            problems.append(f"remove_dc must be true or false, got {self.remove_dc!r}")
        for name, (lo, hi, why) in RANGES.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                problems.append(f"{name} must be a number from {lo:g} to {hi:g}, "
                                f"got {v!r}")
            elif not lo <= v <= hi:  # NaN fails this too
                problems.append(f"{name} must be from {lo:g} to {hi:g}, got {v!r}: {why}")
        if problems:  # the comparisons below need numbers
            raise EmgSettingsError("EMG processing settings: " + "; ".join(problems))
        if not 0 < self.highpass_hz < self.lowpass_hz:
            problems.append(f"need 0 < highpass_hz < lowpass_hz, got {self.highpass_hz} "
                            f"and {self.lowpass_hz}")
        for name in ("bandpass_order", "envelope_order"):
            order = getattr(self, name)
            if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= 8:
                problems.append(f"{name} must be an integer from 1 to 8, got {order!r}")
        if self.notch_hz is not None and (isinstance(self.notch_hz, bool)
                                          or self.notch_hz not in MAINS_FREQUENCIES):
            problems.append(f"notch_hz must be None, 50 or 60, got {self.notch_hz!r}")
        if not self.notch_q > 0:
            problems.append(f"notch_q must be positive, got {self.notch_q}")
        if self.rectification != "full_wave":
            problems.append(f"rectification must be 'full_wave', got {self.rectification!r}")
        if not self.envelope_hz > 0:
            problems.append(f"envelope_hz must be positive, got {self.envelope_hz}")
        if self.normalisation not in NORMALISATION_METHODS:
            problems.append(f"normalisation must be one of {NORMALISATION_METHODS}, "
                            f"got {self.normalisation!r}")
        if not self.mvc_window_s > 0:
            problems.append(f"mvc_window_s must be positive, got {self.mvc_window_s}")
        if self.precision not in PRECISIONS:
            problems.append(f"precision must be one of {PRECISIONS}, got {self.precision!r}")
        if problems:
            raise EmgSettingsError("EMG processing settings: " + "; ".join(problems))

    @classmethod
    def trunk(cls) -> EmgProcessing:
        """Defaults with a 30 Hz high-pass, for trunk muscles where the ECG reaches."""
        return cls(highpass_hz=30.0)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able form with a version, stable across releases."""
        return {"version": SETTINGS_VERSION, **asdict(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EmgProcessing:
        """Inverse of `to_dict`; unknown keys or another version are an error, missing
        keys take their defaults."""
        data = dict(data)
        version = data.pop("version", SETTINGS_VERSION)
        if version != SETTINGS_VERSION:
            raise EmgSettingsError(f"EMG processing settings version {version!r} is not "
                                   f"{SETTINGS_VERSION}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise EmgSettingsError(f"EMG processing settings: unknown keys {unknown}")
        return cls(**data)


@dataclass(frozen=True, slots=True)
class FilterDesign:
    """The filters for one sampling rate, with the band edges actually used."""

    fs: float
    highpass_hz: float
    lowpass_hz: float
    bandpass: NDArray[np.float64]
    envelope: NDArray[np.float64]

    def to_dict(self) -> dict[str, float]:
        """The effective band (differs from the settings when the upper edge was clipped)."""
        return {"fs": self.fs, "highpass_hz": self.highpass_hz, "lowpass_hz": self.lowpass_hz}


def design(settings: EmgProcessing, fs: float) -> FilterDesign:
    """Second-order sections for `fs`; the notch, when set, is appended to the band-pass.

    Raises EmgSettingsError when `fs` is too low for the settings (the message says
    which edge and what rate would do).
    """
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy import signal

    if not np.isfinite(fs) or fs <= 0:
        raise EmgSettingsError(f"sampling rate must be a positive number of Hz, got {fs}")
    nyquist = fs / 2.0
    high = min(settings.lowpass_hz, NYQUIST_MARGIN * nyquist)
    if high < MIN_UPPER_EDGE_HZ or high <= settings.highpass_hz:
        need = 2.0 * max(MIN_UPPER_EDGE_HZ, settings.highpass_hz) / NYQUIST_MARGIN
        raise EmgSettingsError(
            f"sampling rate {fs:g} Hz is too low for EMG amplitude processing: the band-pass "
            f"upper edge would be {high:g} Hz; record at {need:g} Hz or more (1-4 kHz usual)")
    if settings.envelope_hz >= nyquist:
        raise EmgSettingsError(f"envelope low-pass {settings.envelope_hz} Hz is not below the "
                               f"Nyquist frequency {nyquist:g} Hz")
    bp = signal.butter(settings.bandpass_order, [settings.highpass_hz, high], btype="bandpass",
                       fs=fs, output="sos")
    if settings.notch_hz is not None:
        if settings.notch_hz >= high:
            raise EmgSettingsError(f"notch {settings.notch_hz} Hz lies above the band-pass "
                                   f"upper edge {high:g} Hz")
        b, a = signal.iirnotch(float(settings.notch_hz), settings.notch_q, fs=fs)
        bp = np.vstack([bp, signal.tf2sos(b, a)])
    env = signal.butter(settings.envelope_order, settings.envelope_hz, btype="lowpass", fs=fs,
                        output="sos")
    return FilterDesign(float(fs), float(settings.highpass_hz), float(high),
                        np.asarray(bp, dtype=np.float64), np.asarray(env, dtype=np.float64))


def check_raw(raw: NDArray[Any]) -> FloatArray:
    """`raw` as a finite float64 (n_samples, n_channels) array, or a clear error.

    NaN or infinite samples are refused here (naming the channel and the first sample),
    never filtered into neighbouring samples: `quality.assess` counts them, and
    `fill_non_finite` repairs them explicitly when a caller chooses to.
    """
    arr = np.asarray(raw, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"EMG must be a (n_samples, n_channels) array, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        bad = ~finite
        rows, cols = np.nonzero(bad)
        first = int(np.argmin(rows))
        raise ValueError(f"EMG has {int(bad.sum())} NaN or infinite samples; the first in "
                         f"channel {int(cols[first])} at sample {int(rows[first])}")
    return arr


def fill_non_finite(raw: NDArray[Any]) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Replace NaN/inf samples by linear interpolation between their finite neighbours
    (a channel with none finite becomes zeros); returns the filled copy and the mask of
    replaced samples, so the caller can report them."""
    arr = np.array(raw, dtype=np.float64, copy=True)
    if arr.ndim != 2:
        raise ValueError(f"EMG must be a (n_samples, n_channels) array, got shape {arr.shape}")
    mask = ~np.isfinite(arr)
    idx = np.arange(arr.shape[0])
    for c in np.nonzero(mask.any(axis=0))[0]:
        good = ~mask[:, c]
        arr[:, c] = np.interp(idx, idx[good], arr[good, c]) if good.any() else 0.0
    return arr, mask


def _min_length(design_: FilterDesign) -> int:
    """Samples `sosfiltfilt` needs for its default padding, for the longer cascade."""
    sections = max(len(design_.bandpass), len(design_.envelope))
    return 3 * (2 * sections + 1) + 1


def _check_length(n: int, design_: FilterDesign) -> None:
    need = _min_length(design_)
    if n < need:
        raise ValueError(f"EMG has {n} samples; the zero-phase filters need at least {need}")


def condition(raw: NDArray[Any], fs: float, settings: EmgProcessing) -> FloatArray:
    """Steps 1-3 (DC removal, band-pass, notch): the conditioned signal, float64."""
    arr = np.ascontiguousarray(check_raw(raw))
    d = design(settings, fs)
    _check_length(arr.shape[0], d)
    out = np.empty(arr.shape, dtype=np.float64)
    zero_phase(d.bandpass.astype(_dtype(settings)), arr, out, offset=_offsets(arr, settings),
               threads=_threads(arr))
    return out


def process(raw: NDArray[Any], fs: float, settings: EmgProcessing) -> FloatArray:
    """Steps 1-5: the linear envelope in volts, same shape as `raw`, float64.

    The filters run in place in the output (`zero_phase.zero_phase`, eight channels side
    by side, blocks of channels on the machine's cores), so the memory beyond the input
    and the output is the filters' padding (an hour of 16 channels at 2 kHz is 0.9 GB
    in float64). The result is scipy's `sosfiltfilt` per channel, to rounding.
    """
    arr = np.ascontiguousarray(check_raw(raw))
    d = design(settings, fs)
    _check_length(arr.shape[0], d)
    out = np.empty(arr.shape, dtype=np.float64)
    dtype = _dtype(settings)
    threads = _threads(arr)
    zero_phase(d.bandpass.astype(dtype), arr, out, offset=_offsets(arr, settings),
               threads=threads)
    zero_phase(d.envelope.astype(dtype), out, out, rectify=True, threads=threads)
    return out


def _dtype(settings: EmgProcessing) -> type[np.floating[Any]]:
    return np.float32 if settings.precision == "float32" else np.float64


def _offsets(arr: FloatArray, settings: EmgProcessing) -> FloatArray:
    """Step 1's DC per channel (its mean), in float64 before any narrowing."""
    if not settings.remove_dc:
        return np.zeros(arr.shape[1])
    return np.asarray(arr.mean(axis=0), dtype=np.float64)


def _threads(arr: FloatArray) -> int:
    """One thread per block of `LANES` channels, at most one per core; short records
    stay on one thread (starting threads would cost more than they save). Splitting
    16 channels into two blocks of 8 for two threads costs 1.3x the CPU time (see
    `zero_phase.LANES`): faster only on idle cores, slower on a shared machine."""
    if arr.shape[0] < THREADED_SAMPLES:
        return 1
    return max(1, min(os.cpu_count() or 1, -(-arr.shape[1] // LANES)))


class EnvelopeStream:
    """Causal envelope for the live strip: the same band-pass, notch, rectification and
    envelope low-pass as `process`, run forward only with filter state kept between
    blocks (`sosfilt` with `zi`), always in float64.

    Causal means: each output sample depends only on samples up to it, so the envelope
    lags (the 4th-order 6 Hz low-pass delays slow changes by about 70 ms, 2.61 / (2 pi
    6 Hz), its group delay at low frequencies) and has the single-pass (not squared)
    magnitude response. It is not the offline envelope and is never used for results.
    DC is removed by the band-pass's high-pass (the filter starts in the steady state
    of the first sample, so an offset does not ring at the start).
    """

    def __init__(self, fs: float, n_channels: int, settings: EmgProcessing | None = None):
        self.settings = settings or EmgProcessing()
        self.design = design(self.settings, fs)
        if n_channels < 1:
            raise ValueError(f"need at least one channel, got {n_channels}")
        self.n_channels = n_channels
        self._filters = CausalEnvelope(self.design.bandpass, self.design.envelope, n_channels)
        self._last = np.zeros(n_channels)
        self.non_finite_samples = 0
        """NaN/inf samples received so far; each is replaced by the channel's last finite
        sample (a hold, so no step rings through the band-pass) and counted here."""

    def push(self, block: NDArray[Any]) -> FloatArray:
        """Envelope of the next (n, n_channels) block of raw samples (n may be 0)."""
        arr = np.asarray(block, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != self.n_channels:
            raise ValueError(f"block must have shape (n, {self.n_channels}), got {arr.shape}")
        if arr.shape[0] == 0:
            return np.empty((0, self.n_channels))
        bad = ~np.isfinite(arr)
        if bad.any():
            arr = arr.copy()
            self.non_finite_samples += int(bad.sum())
            for c in np.nonzero(bad.any(axis=0))[0]:
                col = arr[:, c]
                held = np.where(bad[:, c], -1, np.arange(len(col)))
                held = np.maximum.accumulate(held)
                arr[:, c] = np.where(held >= 0, col[np.maximum(held, 0)], self._last[c])
        self._last = arr[-1].copy()
        return self._filters.push(arr)
