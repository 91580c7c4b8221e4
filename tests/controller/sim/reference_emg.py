"""The simulated wearer's EMG as plain per-tick numpy, frozen as the oracle for the fast one.

These are `controller.sim.muscles.MuscleModel.activation`, `controller.sim.surface_emg.
SurfaceEmgGenerator` and the generating part of `controller.sim.emg_amplifier.EmgTap`
as they were before the amplifier's per-tick work was cut down (band noise and the hum's
time courses computed ahead in blocks, one tick's activation in Python floats). They are
kept verbatim (only renamed, the tap reduced to what it generates and how it stamps) so
`test_emg_reference.py` can check that the simulated amplifier still produces exactly
the samples the reviewed code did, and `bench/bench_emg_simulation.py` can time both.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from controller.device.base import Sample
from controller.sim.muscles import (
    _AGONIST,
    ACTIVE_FLEXION,
    BASELINE,
    CHANNELS,
    CO_CONTRACTION,
    JOINT,
    LUMBAR_TO_HIP,
    MUSCLES,
    SHARES,
    SIDES,
    MuscleModel,
)
from controller.sim.surface_emg import (
    ARTEFACT_DECAY_S,
    ARTEFACT_HZ,
    ARTEFACT_LENGTH_S,
    BAND_ORDER,
    SENSOR_TABLE,
    EmgBlock,
    EmgSettings,
    _unit_noise_gain,
)

FloatArray = NDArray[np.float64]
N_SPARE = 4
SAMPLES_PER_TICK = 20


class ReferenceMuscles:
    """`MuscleModel.activation` as it was, on a model's maxima."""

    def __init__(self, model: MuscleModel) -> None:
        self.max_nm = model.max_nm

    def activation(self, human_nm: ArrayLike, exo_nm: ArrayLike) -> FloatArray:
        """Activation (K, 12) in `CHANNELS` order from the wearer's hip extension moments
        and the exoskeleton's extension torques, both (K, 2) Nm (left, right) or (2,)."""
        m = np.atleast_2d(np.asarray(human_nm, dtype=np.float64))
        t = np.atleast_2d(np.asarray(exo_nm, dtype=np.float64))
        if m.shape[-1] != 2 or t.shape != m.shape:
            raise ValueError(f"moments and torques must both be (K, 2), got {m.shape}, {t.shape}")
        hip = m - t  # (K, 2) net hip extension demand per leg
        lumbar = LUMBAR_TO_HIP * hip.sum(axis=1)  # (K,) net about L5/S1, whole trunk
        out = np.empty((m.shape[0], len(CHANNELS)))
        col = {ch: i for i, ch in enumerate(CHANNELS)}
        for s, side in enumerate(SIDES):
            demand = {
                "lumbar_extension": np.maximum(0.5 * lumbar, 0.0),
                "hip_extension": np.maximum(hip[:, s], 0.0),
                "lumbar_flexion": ACTIVE_FLEXION * np.maximum(-0.5 * lumbar, 0.0),
                "hip_flexion": ACTIVE_FLEXION * np.maximum(-hip[:, s], 0.0),
            }
            for muscle in MUSCLES:
                # share x demand over share x maximum: the muscle's own maximum holds
                # its share already (`max_nm`), so the demand takes it here.
                need = SHARES[muscle] * demand[JOINT[muscle]] / self.max_nm[(muscle, side)]
                out[:, col[(muscle, side)]] = np.clip(need, 0.0, 1.0)
            for muscle, agonist in _AGONIST.items():
                c = col[(muscle, side)]
                out[:, c] = np.clip(
                    out[:, c] + CO_CONTRACTION[muscle] * out[:, col[(agonist, side)]], 0.0, 1.0
                )
        base = np.array([BASELINE[mu] for mu, _ in CHANNELS])
        return np.asarray(base + (1.0 - base) * out, dtype=np.float64)


class ReferenceGenerator:
    """`controller.sim.surface_emg.SurfaceEmgGenerator` as it was: every block draws,
    filters and mixes its own samples."""

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
        self._zi = np.zeros((self._sos.shape[0], 2, n_channels))
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
        knots = np.vstack([prev, activation])  # (K + 1, ch)
        frac = (np.arange(1, self.upsample + 1) / self.upsample)[None, :, None]
        out = (1.0 - frac) * knots[:-1, None, :] + frac * knots[1:, None, :]
        self._last_activation = activation[-1:].copy()
        return out.reshape(-1, self.n_channels)

    def push(self, activation: ArrayLike) -> EmgBlock:
        """The samples for `activation` (K, ch) at the tick rate, or (ch,) for one tick."""
        a = np.atleast_2d(np.asarray(activation, dtype=np.float64))
        if a.shape[1] != self.n_channels:
            raise ValueError(f"activation has {a.shape[1]} channels, expected {self.n_channels}")
        if not np.all(np.isfinite(a)):
            raise ValueError("activation must be finite")
        return self._generate(np.clip(self._interpolate(a), 0.0, 1.0))

    def push_samples(self, activation: ArrayLike) -> EmgBlock:
        """Like `push`, with activation already at the sample rate (n, ch)."""
        a = np.atleast_2d(np.asarray(activation, dtype=np.float64))
        if a.shape[1] != self.n_channels:
            raise ValueError(f"activation has {a.shape[1]} channels, expected {self.n_channels}")
        self._last_activation = a[-1:].copy()
        return self._generate(np.clip(a, 0.0, 1.0))

    def _generate(self, act: FloatArray) -> EmgBlock:
        s = self.settings
        n = act.shape[0]
        start = self._n
        shape = (n, self.n_channels)
        white = self._muscle_rng.standard_normal(shape, dtype=np.float32)
        band, self._zi = signal.sosfilt(self._sos, white, axis=0, zi=self._zi)
        x = np.asarray(band, dtype=np.float64)
        x *= act
        x *= self.gain_v * self._norm
        rows = np.arange(start, start + n) % self._sensor.shape[0]
        x += self._sensor[rows]
        idx = np.arange(start, start + n)
        t = idx / s.fs
        if s.mains_hz is not None:
            # sin(wt + p) = sin(wt) cos(p) + cos(wt) sin(p) and sin(3u) = 3 sin(u) -
            # 4 sin(u)^3: three time courses per block, mixed per channel in one product.
            w = 2.0 * math.pi * s.mains_hz * t
            sw = np.sin(w)
            x += np.stack([sw, np.cos(w), 3.0 * sw - 4.0 * sw**3], axis=1) @ self._mains_mix
        if self._artefacts:
            x += self._artefact_part(start, n)
        self._n = start + n
        return self._apply_faults(EmgBlock(t, x, act, self.gain_v), idx)

    def _artefact_part(self, start: int, n: int) -> FloatArray:
        out = np.zeros((n, self.n_channels))
        keep: list[tuple[int, FloatArray]] = []
        for at, shape in self._artefacts:
            lo, hi = max(start, at), min(start + n, at + shape.shape[0])
            if lo < hi:
                out[lo - start:hi - start] += shape[lo - at:hi - at]
            if at + shape.shape[0] > start + n:
                keep.append((at, shape))
        self._artefacts = keep
        return out

    def _apply_faults(self, block: EmgBlock, idx: NDArray[np.int64]) -> EmgBlock:
        f = self.settings.faults
        x = block.samples
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




class ReferenceTap:
    """What `EmgTap.emit` generated per tick, and its spread stamps, as it was."""

    def __init__(self, muscles: MuscleModel, seed: int) -> None:
        self.muscles = ReferenceMuscles(muscles)
        self.generator = ReferenceGenerator(16, seed, None, SAMPLES_PER_TICK)
        self.onsets = 0
        self._activity: str | None = None
        self.last_stamp: float | None = None

    def emit(self, sample: Sample, human: tuple[float, float],
             exo: tuple[float, float]) -> EmgBlock:
        """The tick's block from the wearer's moments and the exoskeleton's torques."""
        activity = sample.truth.activity if sample.truth is not None else None
        if self._activity is not None and activity != self._activity:
            self.generator.onset()
            self.onsets += 1
        self._activity = activity
        act = self.muscles.activation(human, exo)[0]
        return self.generator.push(np.concatenate([act, np.zeros(N_SPARE)]))

    def spread_stamps(self, block: EmgBlock, now: float, late_s: float = 0.0) -> list[float]:
        """The stamps `EmgTap._push_spread` gave a block read at `now`."""
        n = block.samples.shape[0]
        now = now - late_s
        period = 1.0 / self.generator.settings.fs
        prev = self.last_stamp if self.last_stamp is not None else now - n * period
        last = max(now, prev + n * 1e-7)
        stamps = prev + (last - prev) * np.arange(1, n + 1) / n
        self.last_stamp = last
        return list(stamps.tolist())
