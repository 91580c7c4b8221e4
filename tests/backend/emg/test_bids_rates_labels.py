"""BIDS-EMG export of every rate an import accepts, and BDF labels unique in 16 characters
(regressions: 2048 Hz and 1 Hz raised in `bdf_bytes`; `erector_spinae_l...` left and right
collided when cut to 16 characters)."""

from __future__ import annotations

import io
from types import SimpleNamespace

import edfio
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from backend.emg import bids


@pytest.mark.parametrize("fs", [2048.0, 512.0, 1024.0, 1.0, 2000.0, 4000.0, 2048.5])
def test_bdf_holds_whole_samples_at_each_accepted_rate(fs: float) -> None:
    n = max(3, int(fs * 1.5))
    x = np.linspace(-1e-3, 1e-3, n).reshape(-1, 1)
    data = bids.bdf_bytes(x, fs, ["ES-L"])
    bdf = edfio.read_bdf(io.BytesIO(data))
    sig = bdf.signals[0]
    assert sig.sampling_frequency == pytest.approx(fs)
    assert np.allclose(sig.data[:n], x[:, 0] * 1e6, atol=1e-3)
    per = fs * bids.record_duration(fs)
    assert per == round(per)


@given(st.floats(min_value=1.0, max_value=100_000.0, allow_nan=False))
def test_record_duration_is_whole_samples_or_refused(fs: float) -> None:
    try:
        d = bids.record_duration(fs)
    except ValueError as exc:
        assert repr(fs) in str(exc)
        return
    assert abs(fs * d - round(fs * d)) <= 1e-9 * fs * d


def test_a_rate_no_record_holds_is_refused_naming_it() -> None:
    with pytest.raises(ValueError, match=r"1000\.0001"):
        bids.record_duration(1000.0001)


def test_long_labels_stay_unique_and_keep_the_full_name() -> None:
    labels = ["erector_spinae_left", "erector_spinae_right", "GM-R", "rectus_femoris_l"]
    names = bids.bdf_labels(labels)
    assert len(set(names)) == 4
    assert all(len(n) <= 16 for n in names)
    assert names[2:] == ["GM-R", "rectus_femoris_l"]
    assert names[:2] == ["erector_spinae~1", "erector_spinae~2"]
    chans = [{"label": lb, "muscle": "m", "side": "left"} for lb in labels]
    cols, rows = bids.channels_rows(SimpleNamespace(channels=chans), {})  # type: ignore[arg-type]
    assert [r[0] for r in rows] == names
    assert [r[cols.index("description")] for r in rows] == [f"montage label {lb}"
                                                            for lb in labels]
    data = bids.bdf_bytes(np.zeros((10, 4)), 10.0, labels)
    assert [s.label for s in edfio.read_bdf(io.BytesIO(data)).signals] == names
