"""Montage records, validation and channel-label matching."""

from __future__ import annotations

import pytest

from controller.emg.montage import Montage, MontageChannel, MontageError

ES_L = MontageChannel("ES-L lumbar", "erector_spinae_lumbar", "left",
                      placement="2 finger widths lateral to L1", electrode_type="Ag/AgCl",
                      inter_electrode_distance_mm=20.0, reference="C7")
GM_R = MontageChannel("GM R", "gluteus_maximus", "right")


def test_round_trip() -> None:
    m = Montage((ES_L, GM_R))
    assert Montage.from_dict(m.to_dict()) == m
    assert m.to_dict()["channels"][0]["inter_electrode_distance_mm"] == 20.0


def test_labels_match_loosely_and_report_leftovers() -> None:
    m = Montage((ES_L, GM_R))
    found = m.match(["TRIG", "gm_r", "es_l_LUMBAR"])
    assert found.indices == (2, 1)
    assert found.unmatched_labels == ("TRIG",)
    assert found.complete
    assert m.require(["gm.r", "es l lumbar"]) == (1, 0)


def test_missing_channels_are_named() -> None:
    m = Montage((ES_L, GM_R))
    assert m.match(["EMG1", "GM R"]).missing == ("ES-L lumbar",)
    with pytest.raises(MontageError, match=r"\['ES-L lumbar'\].*EMG1"):
        m.require(["EMG1", "GM R"])


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"label": " ", "muscle": "gluteus_maximus", "side": "left"}, "empty"),
    ({"label": "x", "muscle": "deltoid", "side": "left"}, "unknown muscle"),
    ({"label": "x", "muscle": "gluteus_maximus", "side": "both"}, "side"),
    ({"label": "x", "muscle": "gluteus_maximus", "side": "left",
      "inter_electrode_distance_mm": 0.0}, "inter-electrode"),
])
def test_bad_channels(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(MontageError, match=message):
        MontageChannel.from_dict(kwargs)


def test_duplicates_are_refused() -> None:
    with pytest.raises(MontageError, match="unique"):
        Montage((ES_L, MontageChannel("es_l_lumbar", "rectus_femoris", "left")))
    with pytest.raises(MontageError, match="at most once"):
        Montage((GM_R, MontageChannel("other", "gluteus_maximus", "right")))
    with pytest.raises(MontageError, match="same label"):
        Montage((GM_R,)).match(["GM R", "gm-r"])
