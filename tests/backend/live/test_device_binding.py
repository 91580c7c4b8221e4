"""Which device a profile belongs to (backend/live/device_binding.py), and the runtime
applying a profile's layout only to that device."""

from __future__ import annotations

from backend.live.device_binding import BoundDevice, firmware_notice, mismatch
from controller.device.base import DeviceIdentity

ID_A = "0123456789abcdef0123456789abcdef"
ID_B = "fedcba9876543210fedcba9876543210"
REAL = BoundDevice("udp", "00112233aabbccdd", ID_A, "exo-nucleo 3")


def test_the_same_device_matches_whatever_its_firmware() -> None:
    newer = BoundDevice("udp", REAL.key_id, ID_A, "exo-nucleo 4")
    assert mismatch(REAL, newer) == ""
    notice = firmware_notice(REAL, newer)
    assert "'exo-nucleo 3' then" in notice and "'exo-nucleo 4' now" in notice
    assert firmware_notice(REAL, REAL) == ""


def test_another_device_key_or_kind_is_named() -> None:
    assert mismatch(REAL, BoundDevice("udp", REAL.key_id, ID_B, "exo-nucleo 3")) == (
        f"made on device {ID_A}, this is device {ID_B}")
    assert "key 99" in mismatch(REAL, BoundDevice("udp", "99", ID_A, "exo-nucleo 3"))
    sim = BoundDevice("udp-sim", REAL.key_id, ID_A, "exostudy-sim 3")
    assert mismatch(sim, REAL) == "made on a udp-sim device, this is a udp device"
    # A profile from before protocol 3 has no unique id: it matches no device.
    old = BoundDevice("udp", REAL.key_id, "", "not reported (protocol 2)")
    assert "before devices reported a unique id" in mismatch(old, REAL)


def test_of_takes_the_identity_the_link_proved() -> None:
    ident = DeviceIdentity(ID_A, "exo-sbc 3", "00112233aabbccdd", 77)
    b = BoundDevice.of("udp", ident)
    assert b == BoundDevice("udp", "00112233aabbccdd", ID_A, "exo-sbc 3")
    assert ID_A in b.describe() and "'exo-sbc 3'" in b.describe()
    assert "in-process" in BoundDevice("sim", "", "", "x").describe()
