"""The worker's check that a controller's encoder layout belongs to the device on the
link (backend/worker/device_gate.py); the real processes are in
tests/faults/test_device_gate_faults.py."""

from __future__ import annotations

from backend.worker.device_gate import DeviceGate
from controller.device.base import DeviceIdentity

ID_A = "a1" * 16
ID_B = "b2" * 16
GATE = DeviceGate(4, "00112233aabbccdd", ID_A)


def test_the_profiles_own_device_passes_whatever_its_firmware_or_boot() -> None:
    assert GATE.refusal(DeviceIdentity(ID_A, "exo-nucleo 3", "00112233aabbccdd", 1)) == ""
    assert GATE.refusal(DeviceIdentity(ID_A, "exo-nucleo 4", "00112233aabbccdd", 2)) == ""


def test_no_identity_another_device_or_key_is_refused_naming_both() -> None:
    unproved = GATE.refusal(None)
    assert "not proved its identity" in unproved and ID_A in unproved
    other = GATE.refusal(DeviceIdentity(ID_B, "exo-sbc 3", "00112233aabbccdd", 1))
    assert ID_A in other and ID_B in other and "hardware profile 4" in other
    assert GATE.refusal(DeviceIdentity(ID_A, "exo-nucleo 3", "99", 1)) != ""
