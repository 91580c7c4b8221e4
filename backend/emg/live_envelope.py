"""The live page's EMG strip, server side: each subscribed channel's causal envelope as
samples arrive, decimated for display, with per-channel flags, as `LiveEmg` messages.

Why causal: the strip must move with the wearer, so `EnvelopeStream` (the study's
band-pass, notch, rectification and 6 Hz envelope, run forward only with its state kept
between blocks) turns each pulled block into envelope samples at once. It lags like any
causal low-pass and is never used for results; the stored raw samples are.

Display rate, `DISPLAY_HZ` = 50 Hz: the envelope holds nothing above its low-pass
(6 Hz by default, 4th order: at 25 Hz, the Nyquist frequency of 50 Hz, it is down by
(25/6)^4, about 50 dB), so keeping every k-th sample needs no further anti-alias filter
and adds no delay. 50 Hz is 500 points per channel in the page's 10 s window, about
one per pixel of the strip, and 16 channels x 50 Hz is 800 values a second on the
WebSocket, a third of what the 100 Hz tick columns already send.

Messages: at most one per `MIN_INTERVAL_S` (25 a second) per subscription, so a
2 kHz stream that arrives in 10 ms chunks does not flood a console's queue; a value
waits at most that long (plus the pull) before it is sent. This keeps the amplifier's
push to the console well under 100 ms (bench/bench_emg_live.py measures it).

Flags per channel, as the strip shows them: `non_finite` counts NaN or infinite samples
since the subscription connected (the envelope holds the last finite sample over them);
`clipping` and `flat` describe the last `FLAG_WINDOW_S` of raw samples with the same
tests and thresholds as the stored recording's quality (`controller.emg.quality`):
samples in runs at the window's own extremes, and an RMS after DC removal below
`FLAT_LINE_RMS_V`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from backend.schemas.live import EmgChannelFlags, LiveEmg
from controller.emg import quality
from controller.emg.processing import EmgProcessing, EnvelopeStream

DISPLAY_HZ = 50.0
MIN_INTERVAL_S = 0.04
FLAG_WINDOW_S = 0.5

Publish = Callable[[dict[str, Any]], None]


class LiveEnvelope:
    """Causal envelope, decimation and flags of one subscription's stream."""

    def __init__(self, fs: float, labels: list[str], session_id: int, subscription_id: int,
                 settings: EmgProcessing | None = None, publish: Publish | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.fs = float(fs)
        self.labels = list(labels)
        self.session_id = session_id
        self.subscription_id = subscription_id
        self.recording_id: int | None = None
        #: The inlet's clock correction added to the stamps pushed (sent with each message).
        self.clock_correction_s = 0.0
        n = len(labels)
        self.stream = EnvelopeStream(self.fs, n, settings)
        #: Keep every `step`-th envelope sample (the display rate is fs / step).
        self.step = max(1, round(self.fs / DISPLAY_HZ))
        self.publish = publish
        self.clock = clock
        self.non_finite = np.zeros(n, dtype=np.int64)
        self.clipping = np.zeros(n, dtype=bool)
        self.flat = np.zeros(n, dtype=bool)
        self.messages = 0
        self._window = max(2, round(FLAG_WINDOW_S * self.fs))
        self._raw: list[NDArray[np.float64]] = []
        self._raw_n = 0
        self._seen = 0
        self._t: list[float] = []
        self._v: list[NDArray[np.float64]] = []
        self._last_sent = -np.inf
        self._t_end = 0.0
        #: The flags as sent, rebuilt only when a flag or count changed (a message
        #: every 40 ms, the flags every 0.5 s).
        self._flag_list: list[EmgChannelFlags] | None = None

    @property
    def display_hz(self) -> float:
        """The rate of the values sent."""
        return self.fs / self.step

    def push(self, timestamps: NDArray[Any], samples: NDArray[Any]) -> LiveEmg | None:
        """Take a block (session-clock stamps, volts in montage order); returns the
        message it sent, if one was due."""
        x = np.asarray(samples, dtype=np.float64)
        t = np.asarray(timestamps, dtype=np.float64)
        if x.shape[0] == 0:
            return None
        finite = np.isfinite(x)
        if not finite.all():
            self.non_finite += (~finite).sum(axis=0)
            self._flag_list = None
        self._flags(x)
        env = self.stream.push(x)
        # Keep the rows whose global sample number is on the display grid.
        first = -self._seen % self.step
        self._seen += x.shape[0]
        self._t.extend(t[first::self.step].tolist())
        self._v.extend(env[first::self.step])
        self._t_end = float(t[-1])
        now = self.clock()
        if not self._t or now - self._last_sent < MIN_INTERVAL_S:
            return None
        self._last_sent = now
        return self._send()

    def _flags(self, x: NDArray[np.float64]) -> None:
        self._raw.append(x)
        self._raw_n += x.shape[0]
        if self._raw_n < self._window:
            return
        w = np.concatenate(self._raw)
        self._raw, self._raw_n = [], 0
        self.clipping[:] = quality.clipped_counts(w) > 0
        # A channel with no finite sample (RMS NaN) is flat.
        self.flat[:] = ~(quality.dc_removed_rms(w) >= quality.FLAT_LINE_RMS_V)
        self._flag_list = None

    def message(self) -> LiveEmg:
        """The envelope values gathered since the last message (and clears them)."""
        v = np.asarray(self._v).reshape(len(self._v), len(self.labels))
        if self._flag_list is None:
            self._flag_list = [
                EmgChannelFlags(clipping=bool(self.clipping[c]), flat=bool(self.flat[c]),
                                non_finite=int(self.non_finite[c]))
                for c in range(len(self.labels))]
        msg = LiveEmg(
            session_id=self.session_id, subscription_id=self.subscription_id,
            recording_id=self.recording_id, fs=self.display_hz, t=list(self._t),
            t_end=self._t_end, clock_correction_s=self.clock_correction_s,
            sent_at=time.time(), labels=self.labels,
            values=v.T.tolist(), flags=list(self._flag_list))
        self._t, self._v = [], []
        return msg

    def _send(self) -> LiveEmg:
        msg = self.message()
        self.messages += 1
        if self.publish is not None:
            self.publish(msg.model_dump(mode="json"))
        return msg
