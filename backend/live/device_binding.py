"""Which device a hardware profile belongs to, and whether the one on the link is it.

A profile's encoder zeros and directions are those of one exoskeleton: applied to
another, they shift its angles (by degrees) and with them every lock decision. So a
profile is bound to the identity the device proves when the host joins it (protocol 3
CHALLENGE: its unique id and firmware, under the link key named by its key id) and is
applied only while that same device is on the link; a new firmware on the same device
is shown as a notice, not refused (the mounting did not change).
"""

from __future__ import annotations

from dataclasses import dataclass

from controller.device.base import DeviceIdentity


@dataclass(frozen=True, slots=True)
class BoundDevice:
    """A device as profiles and drafts record it: `kind` (`sim`, `udp-sim`, `udp`), the
    link key's id, the unique id and the firmware it reported ("" where there is none:
    the in-process simulator has no link)."""

    kind: str
    key_id: str
    unique_id: str
    firmware: str

    @classmethod
    def of(cls, kind: str, identity: DeviceIdentity) -> BoundDevice:
        """The record of a device that proved `identity` on the link."""
        return cls(kind, identity.key_id, identity.unique_id, identity.firmware)

    def describe(self) -> str:
        """The identity as the console shows it."""
        if self.kind == "sim":
            return "the in-process simulator (no link)"
        return (f"{self.kind} device {self.unique_id or '(no unique id)'}, firmware "
                f"{self.firmware or '(not reported)'!r}, key id {self.key_id or '-'}")


def mismatch(made_on: BoundDevice, now: BoundDevice) -> str:
    """Why `now` is not the device `made_on` describes ("" if it is the same device).
    Kind, key id and unique id must all match; an empty unique id (a profile from
    before protocol 3) matches no device on a link."""
    if made_on.kind != now.kind:
        return f"made on a {made_on.kind} device, this is a {now.kind} device"
    if made_on.key_id != now.key_id:
        return (f"made under link key {made_on.key_id or '-'}, this device uses key "
                f"{now.key_id or '-'}")
    if now.kind != "sim" and not made_on.unique_id:
        return "made before devices reported a unique id (protocol 3)"
    if made_on.unique_id != now.unique_id:
        return f"made on device {made_on.unique_id}, this is device {now.unique_id}"
    return ""


def firmware_notice(made_on: BoundDevice, now: BoundDevice) -> str:
    """A notice when the same device now runs other firmware ("" otherwise)."""
    if made_on.firmware == now.firmware:
        return ""
    return (f"the device's firmware changed since the bring-up ({made_on.firmware!r} then, "
            f"{now.firmware!r} now): the profile still applies; repeat the watchdog and "
            "hardware release steps to check the new firmware")
