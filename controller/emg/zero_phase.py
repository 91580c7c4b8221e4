"""Second-order-section filtering of many channels at once: zero-phase in place (the
offline chain) and causal with its state kept between blocks (the live strip).

`scipy.signal.sosfiltfilt` filters one signal at a time with a per-sample loop whose
every step waits for the previous one (a biquad's output feeds its own state), and it
allocates the padded copy, the forward output and the reversed output of each channel.
An hour of 16-channel EMG runs fourteen such section passes per sample. This kernel
computes the same thing (the same odd-extension padding, the same steady-state initial
conditions, the same section arithmetic in the same order) for a block of channels of
one sample side by side, so the processor advances several independent recurrences per
vector instruction; blocks of channels go to threads (the kernel releases the GIL);
and it writes into the caller's float64 array, so the only memory beyond it is the
padding.

The result equals `sosfiltfilt(sos, x.astype(sos.dtype), axis=0)` (bit for bit on this
machine; tested against scipy to rounding); the arithmetic runs in the dtype of `sos`
(float32 or float64) and every stored value is exactly representable in it, so float32
filtering through a float64 buffer is float32 filtering.

`CausalEnvelope` runs the same section arithmetic forward only, band-pass then
rectification then envelope low-pass, for every channel of a block in one pass: what
`sosfilt` with `zi` gives for the two filters in turn (bit for bit, tested), without
scipy's per-call checks and copies, which cost more than the filtering itself for the
small blocks a live stream arrives in.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

# Channels advanced together by default (the kernel's lanes; a last, partial block is
# padded with zeros). Measured here on the band-pass, CPU time per sample: 16 lanes
# 0.75x of 8 lanes and 0.6x of 32, in both precisions (the lane loop runs as 2-4 vector
# instructions; fewer lanes pay its set-up more often, more lanes spill).
LANES = 16


def pad_length(sos: NDArray[Any]) -> int:
    """`sosfiltfilt`'s default padding for `sos` (3 x its number of taps)."""
    ntaps = 2 * sos.shape[0] + 1
    ntaps -= min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * ntaps


@njit(cache=True, nogil=True)
def _cascade(sos: Any, st: Any, w: int) -> None:  # pragma: no cover - compiled
    """One sample of `w` channels through every section (scipy's transposed direct
    form II, same operation order). `st` holds, per section s from offset 3 * w * s,
    the section's input, then its two states; the last section's output lands where a
    next section's input would be. The lane loop has a run-time length, so the compiler
    vectorises it (numba leaves straight-line code unvectorised: its SLP pass is off)."""
    for s in range(sos.shape[0]):
        b0 = sos[s, 0]
        b1 = sos[s, 1]
        b2 = sos[s, 2]
        a1 = sos[s, 4]
        a2 = sos[s, 5]
        base = 3 * w * s
        for j in range(w):
            x = st[base + j]
            y = b0 * x + st[base + w + j]
            st[base + w + j] = b1 * x - a1 * y + st[base + 2 * w + j]
            st[base + 2 * w + j] = b2 * x - a2 * y
            st[base + 3 * w + j] = y


@njit(cache=True, nogil=True)
def _init(zi: Any, st: Any, x0: Any, w: int) -> None:  # pragma: no cover - compiled
    """Every section's state at the cascade's steady state for a constant input x0."""
    for s in range(zi.shape[0]):
        for j in range(w):
            st[3 * w * s + w + j] = zi[s, 0] * x0[j]
            st[3 * w * s + 2 * w + j] = zi[s, 1] * x0[j]


@njit(cache=True, nogil=True)
def _zero_phase(sos: Any, zi: Any, src: Any, offset: Any, rectify: bool, dst: Any,
                c0: int, c1: int, pad: int, w: int) -> None:  # pragma: no cover - compiled
    """Columns c0:c1 (at most w) of `dst` = zero-phase filter of (src - offset),
    rectified first when asked, with `pad` samples of odd extension at each end, as
    `sosfiltfilt` does; `dst` may be `src` (each sample is read before it is written)."""
    n = src.shape[0]
    g = c1 - c0
    out = 3 * w * sos.shape[0]
    st = np.zeros(out + w, dtype=sos.dtype)
    head = np.zeros((pad + 1, w), dtype=sos.dtype)
    tail = np.zeros((pad + 1, w), dtype=sos.dtype)
    ext = np.zeros((pad, w), dtype=sos.dtype)
    first = np.zeros(w, dtype=sos.dtype)
    for j in range(g):
        for k in range(pad + 1):
            head[k, j] = src[k, c0 + j] - offset[c0 + j]
            tail[k, j] = src[n - 1 - k, c0 + j] - offset[c0 + j]
            if rectify:
                head[k, j] = abs(head[k, j])
                tail[k, j] = abs(tail[k, j])
    # Forward: the odd extension before the start (its output is only state), the
    # signal (stored in dst), then the extension after the end (kept for the backward
    # pass). The state starts at the filter's step response to the first padded sample.
    for j in range(w):
        first[j] = head[0, j] + head[0, j] - head[pad, j]
    _init(zi, st, first, w)
    for i in range(pad):
        for j in range(w):
            st[j] = head[0, j] + head[0, j] - head[pad - i, j]
        _cascade(sos, st, w)
    for i in range(n):
        for j in range(g):
            st[j] = src[i, c0 + j] - offset[c0 + j]
            if rectify:
                st[j] = abs(st[j])
        _cascade(sos, st, w)
        for j in range(g):
            dst[i, c0 + j] = st[out + j]
    for i in range(pad):
        for j in range(w):
            st[j] = tail[0, j] + tail[0, j] - tail[i + 1, j]
        _cascade(sos, st, w)
        for j in range(w):
            ext[i, j] = st[out + j]
    # Backward from the end of the extension; only the signal's part is stored.
    _init(zi, st, ext[pad - 1], w)
    for i in range(pad - 1, -1, -1):
        for j in range(w):
            st[j] = ext[i, j]
        _cascade(sos, st, w)
    for i in range(n - 1, -1, -1):
        for j in range(g):
            st[j] = dst[i, c0 + j]
        _cascade(sos, st, w)
        for j in range(g):
            dst[i, c0 + j] = st[out + j]


@njit(cache=True, nogil=True)
def _causal_envelope(bp: Any, env: Any, bp_st: Any, env_st: Any, src: Any,
                     dst: Any) -> None:  # pragma: no cover - compiled
    """dst = envelope low-pass of |band-pass of src|, rows in order, every column side by
    side; `bp_st` and `env_st` (`_cascade`'s layout) carry on from the previous block."""
    w = src.shape[1]
    bp_out = 3 * w * bp.shape[0]
    env_out = 3 * w * env.shape[0]
    for i in range(src.shape[0]):
        for j in range(w):
            bp_st[j] = src[i, j]
        _cascade(bp, bp_st, w)
        for j in range(w):
            env_st[j] = abs(bp_st[bp_out + j])
        _cascade(env, env_st, w)
        for j in range(w):
            dst[i, j] = env_st[env_out + j]


class CausalEnvelope:
    """Band-pass, full-wave rectification and envelope low-pass, forward only, in float64,
    with the filters' state kept between blocks.

    Equals `sosfilt(envelope, abs(sosfilt(bandpass, x, axis=0, zi=...)), axis=0, zi=...)`
    over the blocks pushed so far, with the band-pass starting in the steady state of the
    first sample (`sosfilt_zi` times it) and the envelope at rest (zeros)."""

    def __init__(self, bandpass: NDArray[Any], envelope: NDArray[Any], n_channels: int) -> None:
        # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
        from scipy import signal

        if n_channels < 1:
            raise ValueError(f"need at least one channel, got {n_channels}")
        self.bandpass = np.ascontiguousarray(bandpass, dtype=np.float64)
        self.envelope = np.ascontiguousarray(envelope, dtype=np.float64)
        self.n_channels = n_channels
        self._zi = np.ascontiguousarray(signal.sosfilt_zi(self.bandpass), dtype=np.float64)
        self._bp_st = np.zeros(3 * n_channels * len(self.bandpass) + n_channels)
        self._env_st = np.zeros(3 * n_channels * len(self.envelope) + n_channels)
        self._started = False

    def push(self, block: NDArray[np.float64]) -> NDArray[np.float64]:
        """The envelope of the next (n, n_channels) finite float64 block."""
        x = np.ascontiguousarray(block, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.n_channels:
            raise ValueError(f"block must have shape (n, {self.n_channels}), got {x.shape}")
        out = np.empty(x.shape)
        if x.shape[0] == 0:
            return out
        if not self._started:
            _init(self._zi, self._bp_st, x[0], self.n_channels)
            self._started = True
        _causal_envelope(self.bandpass, self.envelope, self._bp_st, self._env_st, x, out)
        return out


def zero_phase(sos: NDArray[Any], src: NDArray[np.float64], dst: NDArray[np.float64],
               offset: NDArray[np.float64] | None = None, rectify: bool = False,
               threads: int = 1, lanes: int = LANES) -> None:
    """dst[:, c] = sosfiltfilt(sos, f(src[:, c] - offset[c])) for every column c, with f
    the cast to sos's dtype, then |.| when `rectify`; `dst` may be `src`.

    Both arrays are C-ordered float64 (n_samples, n_channels); `sos` is float32 or
    float64. `threads` > 1 shares blocks of `lanes` channels between threads (the kernel
    releases the GIL); the result depends on neither.
    """
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy import signal

    if sos.dtype not in (np.float32, np.float64) or sos.ndim != 2 or sos.shape[1] != 6:
        raise ValueError(f"sos must be a float32 or float64 (n, 6) array, got {sos.dtype} "
                         f"{sos.shape}")
    if src.dtype != np.float64 or dst.dtype != np.float64:
        raise TypeError("zero_phase works on float64 arrays")
    if src.ndim != 2 or src.shape != dst.shape:
        raise ValueError(f"src and dst must have the same 2-D shape, got {src.shape} and "
                         f"{dst.shape}")
    if not (src.flags.c_contiguous and dst.flags.c_contiguous):
        raise ValueError("zero_phase needs C-ordered arrays")
    if lanes < 1:
        raise ValueError(f"lanes must be positive, got {lanes}")
    pad = pad_length(sos)
    if src.shape[0] <= pad:
        raise ValueError(f"{src.shape[0]} samples; the zero-phase filter needs more than {pad}")
    zi = signal.sosfilt_zi(sos).astype(sos.dtype)
    off = (np.zeros(src.shape[1]) if offset is None
           else np.ascontiguousarray(offset, dtype=np.float64))
    blocks = [(c, min(c + lanes, src.shape[1])) for c in range(0, src.shape[1], lanes)]
    if threads <= 1 or len(blocks) == 1:
        for c0, c1 in blocks:
            _zero_phase(sos, zi, src, off, rectify, dst, c0, c1, pad, lanes)
        return
    with ThreadPoolExecutor(max_workers=min(threads, len(blocks))) as pool:
        for f in [pool.submit(_zero_phase, sos, zi, src, off, rectify, dst, c0, c1, pad, lanes)
                  for c0, c1 in blocks]:
            f.result()
