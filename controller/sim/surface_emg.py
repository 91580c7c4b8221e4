"""Surface EMG at 2 kHz from muscle activation, with the generating truth kept.

Why: the processing chain (band-pass, rectification, envelope, normalisation, quality
flags) must be checkable against a known answer. The generative model is the classic
one for EMG amplitude (Hogan and Mann 1980, IEEE Trans Biomed Eng 27(7):382-395):
zero-mean Gaussian noise, band-limited to 20-450 Hz, whose standard deviation follows
the muscle's activation. Per channel:

    x(t) = g a(t) n(t) + e(t) + h(t) + m(t)

- `n`: white Gaussian noise through a 4th-order Butterworth band-pass 20-450 Hz, scaled
  to unit RMS (the filter's noise gain is computed, not assumed). Its spectrum is flat
  inside the band, a simplification: real sEMG spectra peak around 50-150 Hz.
- `a`: activation (0..1) interpolated linearly from the 100 Hz tick rate to 2 kHz.
- `g`: the channel's RMS at full activation. Default 1 mV RMS x a seeded per-channel
  factor (0.5-1.5: electrode placement, skin, subcutaneous fat). Surface EMG at maximal
  contraction is of the order of a millivolt (De Luca 1997, J Appl Biomech 13:135-163,
  quotes 0-10 mV peak-to-peak for sEMG); 1 mV RMS is this project's assumption.
- `e`: sensor noise, white Gaussian, 3 uV RMS (assumed; amplifier input noise and the
  electrode-skin interface, a few uV RMS for good modern systems), drawn once as a
  65536-sample table per channel and repeated (period 33 s).
- `h`: mains hum at 50 Hz (60 optional) with a weaker 3rd harmonic, a seeded amplitude
  per channel (5-20 uV) and phase (assumed).
- `m`: motion artefacts: at each movement onset every channel gets a damped
  low-frequency transient (1-8 Hz, decay 0.1-0.3 s, amplitude 0.05-0.3 mV, seeded). De
  Luca et al. 2010 (J Biomech 43(8):1573-1579) put motion artefact energy mostly below
  20 Hz, which is why processing high-passes at 20 Hz.

Everything is seeded: every component draws from its own generator, so the output does
not depend on how the stream is cut into blocks (one call for an hour or 20 samples a
tick give the same samples, up to the floating-point order of the hum's per-block matrix
product). The band-limited noise and the hum's time courses depend on the sample clock
only, not on activation, so they are computed `AHEAD` samples at a time (one draw, one
filter call carrying its state) and a tick takes its 20 rows: numpy's per-call overhead
on a tick's tiny arrays was most of the simulated amplifier's cost. Faults for tests
(`Faults`): clipping, flat channels, dropped samples, a stream that stops.

Ground truth kept per sample: the interpolated activation and the generating amplitude
`g a` (the RMS the muscle part has at that instant).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

FloatArray = NDArray[np.float64]

FS_HZ = 2000.0
BAND_HZ = (20.0, 450.0)
BAND_ORDER = 4
FULL_ACTIVATION_RMS_V = 1e-3
SENSOR_NOISE_RMS_V = 3e-6
MAINS_V = (5e-6, 20e-6)  # amplitude range of the hum's fundamental, per channel
ARTEFACT_V = (0.05e-3, 0.3e-3)  # amplitude range of a motion artefact, per channel
ARTEFACT_HZ = (1.0, 8.0)
ARTEFACT_DECAY_S = (0.1, 0.3)
SENSOR_TABLE = 1 << 16
ARTEFACT_LENGTH_S = 1.5  # a transient is cut after this long (e^-5 of it at most left)
#: Samples of band noise and of the clock's time courses computed in one go (2 s).
AHEAD = 4000


@dataclass(frozen=True)
class Faults:
    """Faults to inject (tests of quality flags and of a receiver's robustness).

    `clip_v`: the amplifier saturates at +-clip_v. `flat`: channels that read exactly 0
    (electrode off). `drop_every`: every n-th block of `drop_length` samples is lost (its
    samples and timestamps are absent from the output). `stop_after_s`: nothing is
    produced after this time (a stream that stops mid-trial).
    """

    clip_v: float | None = None
    flat: tuple[int, ...] = ()
    drop_every: int = 0
    drop_length: int = 20
    stop_after_s: float | None = None


@dataclass(frozen=True)
class EmgSettings:
    """What the simulated amplifier records; every default is stated in the docstring."""

    fs: float = FS_HZ
    band_hz: tuple[float, float] = BAND_HZ
    full_activation_rms_v: float = FULL_ACTIVATION_RMS_V
    gain_spread: tuple[float, float] = (0.5, 1.5)
    sensor_noise_rms_v: float = SENSOR_NOISE_RMS_V
    mains_hz: float | None = 50.0
    mains_v: tuple[float, float] = MAINS_V
    artefact_v: tuple[float, float] = ARTEFACT_V
    faults: Faults = field(default_factory=Faults)

    def __post_init__(self) -> None:
        lo, hi = self.band_hz
        if not 0 < lo < hi < self.fs / 2:
            raise ValueError(f"band {self.band_hz} Hz must lie inside (0, {self.fs / 2}) Hz")
        if self.mains_hz not in (None, 50.0, 60.0):
            raise ValueError(f"mains_hz must be None, 50 or 60, got {self.mains_hz}")


@dataclass(frozen=True)
class EmgBlock:
    """Generated samples with their truth. `t` in seconds on the generator's clock
    (sample i of the stream at i / fs); dropped samples are absent from every field."""

    t: FloatArray  # (n,)
    samples: FloatArray  # (n, ch) volts
    activation: FloatArray  # (n, ch) the activation that generated them
    gain_v: FloatArray  # (ch,) RMS of the muscle component at full activation

    @property
    def amplitude_v(self) -> FloatArray:
        """(n, ch) RMS of the muscle component at each sample, g a (the generating truth)."""
        return np.asarray(self.activation * self.gain_v, dtype=np.float64)


def _unit_noise_gain(sos: FloatArray) -> float:
    """RMS of the filter's output for unit-variance white input (sqrt of the impulse
    response's energy)."""
    impulse = np.zeros(1 << 15)
    impulse[0] = 1.0
    h = signal.sosfilt(sos, impulse)
    return float(np.sqrt(np.sum(h * h)))


class SurfaceEmgGenerator:
    """A seeded multi-channel sEMG source, fed with activation, continuous across calls.

    `push(activation)` takes activation at the tick rate (K, ch), `upsample` samples per
    tick, and returns the next K x upsample samples (minus faults). `onset()` starts a
    motion artefact at the next sample.
    """

    def __init__(
        self, n_channels: int, seed: int = 0, settings: EmgSettings | None = None,
        upsample: int = 20,
    ) -> None:
        if n_channels < 1:
            raise ValueError("need at least one channel")
        if upsample < 1:
            raise ValueError("upsample must be >= 1")
        self.settings = s = settings if settings is not None else EmgSettings()
        self.n_channels = n_channels
        self.upsample = upsample
        self.seed = int(seed)
        root = np.random.SeedSequence([0xE36, self.seed])
        fixed, muscle, sensor, artefact = (np.random.default_rng(c) for c in root.spawn(4))
        self._muscle_rng = muscle
        self._artefact_rng = artefact
        #: Per-channel RMS at full activation (V): the generating gain.
        self.gain_v = s.full_activation_rms_v * fixed.uniform(*s.gain_spread, n_channels)
        self.mains_v = fixed.uniform(*s.mains_v, n_channels)
        self.mains_phase = fixed.uniform(0.0, 2.0 * math.pi, n_channels)
        self._sos = signal.butter(BAND_ORDER, s.band_hz, btype="bandpass", fs=s.fs, output="sos")
        self._norm = 1.0 / _unit_noise_gain(self._sos)
        self._scale = self.gain_v * self._norm
        self._zi = np.zeros((self._sos.shape[0], 2, n_channels))
        #: Band noise at unit RMS drawn and filtered ahead; the next sample's row.
        self._band = np.empty((0, n_channels))
        self._band_at = 0
        #: The clock's time courses from sample `_clock_at` on: time (s) and, with
        #: mains, the hum's three (`_mains_basis`).
        self._clock_at = 0
        self._t = np.empty(0)
        self._basis = np.empty((0, 3))
        #: Interpolation weights of the previous and of the current tick's activation.
        frac = (np.arange(1, upsample + 1) / upsample)[:, None]
        self._w_prev = 1.0 - frac
        self._w_next = frac
        f = s.faults
        self._faulty = (f.clip_v is not None or bool(f.flat) or f.drop_every > 0
                        or f.stop_after_s is not None)
        #: Sensor noise: a table of SENSOR_TABLE samples per channel, drawn once and
        #: repeated (a 33 s period at 2 kHz, invisible to amplitude analysis); drawing it
        #: afresh for every sample would double the generator's cost.
        self._sensor = s.sensor_noise_rms_v * sensor.standard_normal((SENSOR_TABLE, n_channels))
        self._mains_mix = np.vstack([
            self.mains_v * np.cos(self.mains_phase),
            self.mains_v * np.sin(self.mains_phase),
            0.2 * self.mains_v,
        ])
        self._n = 0  # samples generated so far (dropped ones included)
        self._last_activation: FloatArray | None = None
        self._artefacts: list[tuple[int, FloatArray]] = []  # (start sample, (L, ch) shape)

    @property
    def samples_generated(self) -> int:
        """Samples generated so far, dropped ones included (the stream's sample clock)."""
        return self._n

    def onset(self) -> None:
        """A movement starts now: a motion artefact on every channel from the next sample."""
        s = self.settings
        r = self._artefact_rng
        n = int(ARTEFACT_LENGTH_S * s.fs)
        t = np.arange(n)[:, None] / s.fs
        amp = r.uniform(*s.artefact_v, self.n_channels) * r.choice([-1.0, 1.0], self.n_channels)
        freq = r.uniform(*ARTEFACT_HZ, self.n_channels)
        tau = r.uniform(*ARTEFACT_DECAY_S, self.n_channels)
        shape = amp * np.exp(-t / tau) * np.sin(2.0 * math.pi * freq * t)
        self._artefacts.append((self._n, shape))

    def _interpolate(self, activation: FloatArray) -> FloatArray:
        """Tick-rate activation to the sample rate: linear from the previous tick's value
        to each tick's value over its `upsample` samples (the tick's last sample equals
        the tick's activation)."""
        prev = activation[:1] if self._last_activation is None else self._last_activation
        if activation.shape[0] == 1:  # one tick: (upsample, 1) weights x (1, ch)
            out = self._w_prev * prev
            out += self._w_next * activation
        else:
            knots = np.vstack([prev, activation])  # (K + 1, ch)
            out = (self._w_prev[None] * knots[:-1, None, :]
                   + self._w_next[None] * knots[1:, None, :]).reshape(-1, self.n_channels)
        self._last_activation = activation[-1:].copy()
        return out

    def push(self, activation: ArrayLike) -> EmgBlock:
        """The samples for `activation` (K, ch) at the tick rate, or (ch,) for one tick."""
        a = np.asarray(activation, dtype=np.float64)
        a = a[None, :] if a.ndim == 1 else np.atleast_2d(a)
        if a.shape[1] != self.n_channels:
            raise ValueError(f"activation has {a.shape[1]} channels, expected {self.n_channels}")
        if not np.isfinite(a).all():
            raise ValueError("activation must be finite")
        return self._generate(_clip_unit(self._interpolate(a)))

    def push_samples(self, activation: ArrayLike) -> EmgBlock:
        """Like `push`, with activation already at the sample rate (n, ch)."""
        a = np.atleast_2d(np.asarray(activation, dtype=np.float64))
        if a.shape[1] != self.n_channels:
            raise ValueError(f"activation has {a.shape[1]} channels, expected {self.n_channels}")
        self._last_activation = a[-1:].copy()
        return self._generate(_clip_unit(a.copy()))

    def _generate(self, act: FloatArray) -> EmgBlock:
        n = act.shape[0]
        start = self._n
        x = self._band_noise(n) * act
        x *= self._scale
        row = start % SENSOR_TABLE
        if row + n <= SENSOR_TABLE:
            x += self._sensor[row:row + n]
        else:
            x += self._sensor[np.arange(start, start + n) % SENSOR_TABLE]
        t, basis = self._clock(start, n)
        if self.settings.mains_hz is not None:
            # Mixed per block, as the time courses' rows come (one product per block).
            x += basis @ self._mains_mix
        if self._artefacts:
            self._add_artefacts(x, start, n)
        self._n = start + n
        block = EmgBlock(t, x, act, self.gain_v)
        return self._apply_faults(block, start) if self._faulty else block

    def _band_noise(self, n: int) -> FloatArray:
        """The next `n` rows of band-limited unit noise (a view: read, never written).
        Drawn and filtered `AHEAD` rows at a time: the draws and the filter run sample
        by sample, so the rows are the same whatever the blocks."""
        have = self._band.shape[0] - self._band_at
        if have < n:
            white = self._muscle_rng.standard_normal((max(n - have, AHEAD), self.n_channels),
                                                     dtype=np.float32)
            band, self._zi = signal.sosfilt(self._sos, white, axis=0, zi=self._zi)
            self._band = np.concatenate([self._band[self._band_at:], band]) if have else band
            self._band_at = 0
        at = self._band_at
        self._band_at = at + n
        return self._band[at:at + n]

    def _clock(self, start: int, n: int) -> tuple[FloatArray, FloatArray]:
        """Time (n,) of samples `start`.. (a copy) and the hum's time courses (n, 3) (a
        view; empty without mains), computed `AHEAD` samples at a time."""
        lo = start - self._clock_at
        if lo < 0 or lo + n > self._t.shape[0]:
            t = np.arange(start, start + max(n, AHEAD)) / self.settings.fs
            self._clock_at, self._t, lo = start, t, 0
            if self.settings.mains_hz is not None:
                self._basis = _mains_basis(self.settings.mains_hz, t)
        return self._t[lo:lo + n].copy(), self._basis[lo:lo + n]

    def _add_artefacts(self, x: FloatArray, start: int, n: int) -> None:
        """Add the motion artefacts running in samples `start`.. to `x` (n, ch); drop
        those that have ended. Overlapping ones are summed first, then added."""
        parts: list[tuple[int, FloatArray]] = []
        keep: list[tuple[int, FloatArray]] = []
        for at, shape in self._artefacts:
            lo, hi = max(start, at), min(start + n, at + shape.shape[0])
            if lo < hi:
                parts.append((lo - start, shape[lo - at:hi - at]))
            if at + shape.shape[0] > start + n:
                keep.append((at, shape))
        self._artefacts = keep
        if len(parts) == 1:
            lo, part = parts[0]
            x[lo:lo + part.shape[0]] += part
        elif parts:
            out = np.zeros_like(x)
            for lo, part in parts:
                out[lo:lo + part.shape[0]] += part
            x += out

    def _apply_faults(self, block: EmgBlock, start: int) -> EmgBlock:
        f = self.settings.faults
        x = block.samples
        idx = np.arange(start, start + x.shape[0])
        if f.clip_v is not None:
            np.clip(x, -f.clip_v, f.clip_v, out=x)
        for ch in f.flat:
            x[:, ch] = 0.0
        keep = np.ones(idx.size, dtype=bool)
        if f.drop_every > 0:
            keep &= (idx // f.drop_length) % f.drop_every != f.drop_every - 1
        if f.stop_after_s is not None:
            keep &= block.t < f.stop_after_s
        if keep.all():
            return block
        return EmgBlock(block.t[keep], x[keep], block.activation[keep], block.gain_v)


def _mains_basis(mains_hz: float, t: FloatArray) -> FloatArray:
    """The hum's three time courses (n, 3) at times `t`: sin(wt + p) = sin(wt) cos(p) +
    cos(wt) sin(p) and sin(3u) = 3 sin(u) - 4 sin(u)^3, so one product with the
    per-channel mix (`_mains_mix`) gives every channel's hum."""
    w = 2.0 * math.pi * mains_hz * t
    sw = np.sin(w)
    return np.stack([sw, np.cos(w), 3.0 * sw - 4.0 * sw**3], axis=1)


def _clip_unit(x: FloatArray) -> FloatArray:
    """`x` clipped to 0..1 in place (np.clip's values without its per-call overhead)."""
    np.maximum(x, 0.0, out=x)
    return np.minimum(x, 1.0, out=x)


def generate(
    activation: ArrayLike, seed: int = 0, settings: EmgSettings | None = None,
    upsample: int = 20, onsets: ArrayLike = (), block_ticks: int = 1000,
) -> EmgBlock:
    """sEMG for a whole recording from tick-rate activation (K, ch), in blocks of
    `block_ticks` ticks (bounded memory for the intermediate arrays). `onsets` are tick
    indices where a movement starts (a motion artefact on every channel)."""
    a = np.atleast_2d(np.asarray(activation, dtype=np.float64))
    gen = SurfaceEmgGenerator(a.shape[1], seed, settings, upsample)
    marks = np.sort(np.asarray(onsets, dtype=np.int64).ravel())
    cuts = sorted({0, a.shape[0], *range(0, a.shape[0], block_ticks),
                   *(int(m) for m in marks if 0 <= m < a.shape[0])})
    total = a.shape[0] * upsample
    t = np.empty(total)
    x = np.empty((total, a.shape[1]))
    act = np.empty((total, a.shape[1]))
    at = 0
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        if np.any(marks == lo):
            gen.onset()
        part = gen.push(a[lo:hi])
        m = part.t.size
        t[at:at + m], x[at:at + m], act[at:at + m] = part.t, part.samples, part.activation
        at += m
    return EmgBlock(t[:at], x[:at], act[:at], gen.gain_v)
