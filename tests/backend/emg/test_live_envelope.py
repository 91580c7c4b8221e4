"""The live strip's envelope on the server: the causal envelope decimated to the display
rate on a fixed sample grid (whatever the block sizes), the per-channel flags, at most
one message per interval, and messages that encode as strict JSON."""

from __future__ import annotations

import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from backend.emg.live_envelope import DISPLAY_HZ, MIN_INTERVAL_S, LiveEnvelope
from backend.schemas.live import EmgChannelFlags, LiveEmg
from controller.emg import quality
from controller.emg.processing import EnvelopeStream

FS = 2000.0


class Clock:
    """A clock the test moves."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _signal(n: int) -> np.ndarray:
    rng = np.random.default_rng(2)
    x = rng.normal(0, 100e-6, (n, 3))
    x[:, 1] = 0.0  # electrode off
    x[:, 2] = np.clip(x[:, 2] * 20, -1e-3, 1e-3)  # at the rails
    return x


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=300), min_size=1, max_size=40))
def test_values_are_every_40th_envelope_sample_whatever_the_blocks(sizes: list[int]) -> None:
    n = sum(sizes)
    x = _signal(n)
    t = 100.0 + np.arange(n) / FS
    clock = Clock()
    sent: list[dict] = []
    live = LiveEnvelope(FS, ["a", "b", "c"], 1, 2, publish=sent.append, clock=clock)
    k = 0
    for size in sizes:
        clock.now += MIN_INTERVAL_S  # every block may send
        live.push(t[k:k + size], x[k:k + size])
        k += size
    last = live.message()  # what is still gathered
    got_t = [v for m in sent for v in m["t"]] + last.t
    got = np.concatenate([np.asarray(m["values"]).reshape(3, -1) for m in sent]
                         + [np.asarray(last.values).reshape(3, -1)], axis=1)
    step = round(FS / DISPLAY_HZ)
    whole = EnvelopeStream(FS, 3).push(x)
    np.testing.assert_array_equal(got_t, t[::step])
    np.testing.assert_allclose(got.T, whole[::step], rtol=1e-9, atol=1e-15)


def test_flags_describe_the_last_half_second_and_nan_is_counted() -> None:
    x = _signal(4000)
    x[1500:1507, 0] = np.nan
    live = LiveEnvelope(FS, ["a", "b", "c"], 1, 2, clock=Clock())
    live.push(np.arange(4000) / FS, x)
    msg = live.message()
    assert [f.non_finite for f in msg.flags] == [7, 0, 0]
    assert [f.flat for f in msg.flags] == [False, True, False]
    assert [f.clipping for f in msg.flags] == [False, False, True]
    # The electrode comes back: the next half second clears the flat flag.
    y = _signal(1000)
    y[:, 1] = np.random.default_rng(9).normal(0, 50e-6, 1000)
    live.push(2.0 + np.arange(1000) / FS, y)
    assert [f.flat for f in live.message().flags] == [False, False, False]
    assert live.message().flags[0].non_finite == 7  # counted since the stream connected


def test_at_most_one_message_per_interval_and_strict_json() -> None:
    clock = Clock()
    sent: list[dict] = []
    live = LiveEnvelope(FS, ["a", "b", "c"], 1, 2, publish=sent.append, clock=clock)
    live.recording_id = 9
    x = _signal(2000)
    x[5, 0] = np.inf
    for k in range(0, 2000, 20):  # 10 ms blocks over 1 s
        clock.now = k / FS
        live.push(k / FS + np.arange(20) / FS, x[k:k + 20])
    assert 1 / MIN_INTERVAL_S - 2 <= len(sent) <= 1 / MIN_INTERVAL_S + 1
    for m in sent:
        text = json.dumps(m, allow_nan=False)
        msg = LiveEmg.model_validate_json(text)
        assert msg.type == "emg" and msg.recording_id == 9 and msg.fs == DISPLAY_HZ
        assert len(msg.values) == 3 and all(len(v) == len(msg.t) for v in msg.values)
        assert msg.t_end >= msg.t[-1]


class _OneChannelAtATime(LiveEnvelope):
    """The strip as it was before it worked on all channels at once: display samples
    picked one by one, flags measured channel by channel, flags rebuilt per message."""

    def push(self, timestamps: np.ndarray, samples: np.ndarray) -> LiveEmg | None:
        x = np.asarray(samples, dtype=np.float64)
        t = np.asarray(timestamps, dtype=np.float64)
        if x.shape[0] == 0:
            return None
        self.non_finite += (~np.isfinite(x)).sum(axis=0)
        self._flags(x)
        env = self.stream.push(x)
        idx = np.arange(self._seen, self._seen + x.shape[0])
        self._seen += x.shape[0]
        for k in np.flatnonzero(idx % self.step == 0):
            self._t.append(float(t[k]))
            self._v.append(env[k])
        self._t_end = float(t[-1])
        now = self.clock()
        if not self._t or now - self._last_sent < MIN_INTERVAL_S:
            return None
        self._last_sent = now
        return self._send()

    def _flags(self, x: np.ndarray) -> None:
        self._raw.append(x)
        self._raw_n += x.shape[0]
        if self._raw_n < self._window:
            return
        w = np.concatenate(self._raw)
        self._raw, self._raw_n = [], 0
        for c in range(w.shape[1]):
            col = w[:, c]
            finite = col[np.isfinite(col)]
            self.clipping[c] = quality.clipped_samples(col) > 0
            self.flat[c] = bool(finite.size == 0 or np.sqrt(np.mean(
                (finite - finite.mean()) ** 2)) < quality.FLAT_LINE_RMS_V)

    def message(self) -> LiveEmg:
        v = np.asarray(self._v).reshape(len(self._v), len(self.labels))
        msg = LiveEmg(
            session_id=self.session_id, subscription_id=self.subscription_id,
            recording_id=self.recording_id, fs=self.display_hz, t=list(self._t),
            t_end=self._t_end, clock_correction_s=self.clock_correction_s,
            sent_at=0.0, labels=self.labels,
            values=[[float(y) for y in v[:, c]] for c in range(v.shape[1])],
            flags=[EmgChannelFlags(clipping=bool(self.clipping[c]), flat=bool(self.flat[c]),
                                   non_finite=int(self.non_finite[c]))
                   for c in range(len(self.labels))])
        self._t, self._v = [], []
        return msg


@settings(max_examples=25, deadline=None)
@given(sizes=st.lists(st.integers(0, 1500), min_size=1, max_size=30),
       holes=st.lists(st.tuples(st.integers(0, 10**6), st.sampled_from([np.nan, np.inf])),
                      max_size=6),
       seed=st.integers(0, 2**32 - 1), off=st.booleans())
def test_messages_equal_the_one_channel_at_a_time_strip(
        sizes: list[int], holes: list[tuple[int, float]], seed: int, off: bool) -> None:
    n = sum(sizes)
    x = _signal(n) * np.random.default_rng(seed).uniform(0.5, 2.0)
    for at, value in holes if n else []:
        x[at % n, at % 3] = value
    if off and n > 1500:  # the first channel's electrode off for a while: nothing finite
        x[500:1500, 0] = np.nan
    t = 100.0 + np.arange(n) / FS
    clock = Clock()
    got: list[dict] = []
    expected: list[dict] = []
    new = LiveEnvelope(FS, ["a", "b", "c"], 1, 2, publish=got.append, clock=clock)
    old = _OneChannelAtATime(FS, ["a", "b", "c"], 1, 2, publish=expected.append, clock=clock)
    k = 0
    for size in sizes:
        clock.now += size / FS  # as fast as the samples come
        new.push(t[k:k + size], x[k:k + size])
        old.push(t[k:k + size], x[k:k + size])
        k += size
    got.append(new.message().model_dump(mode="json"))
    expected.append(old.message().model_dump(mode="json"))
    for m in got + expected:
        m.pop("sent_at")
    assert got == expected
