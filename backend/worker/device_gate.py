"""The device a controller's encoder layout belongs to, checked by the worker itself.

A hardware profile's encoder zeros and directions are those of one exoskeleton; a
controller decoding another device's counts with them sees angles shifted by degrees
and may lock when the wearer did not ask. The server resolves the layout from the
identity the device proved on the link, but the device can change under a running
controller (swapped, or rebooted as another device at the same address), and the
server learns of it only from the worker's next status report. So every `SetController`
whose layout came from a profile carries a `DeviceGate`, and the worker, which sees
every sample, holds the controller to it: no start before the device on the link has
proved to be that one, no lock command on any sample of another device, and a stop to
the released state as soon as another device appears (`backend.worker.machine`).
"""

from __future__ import annotations

from dataclasses import dataclass

from controller.device.base import DeviceIdentity


@dataclass(frozen=True, slots=True)
class DeviceGate:
    """The device (link key id and unique id, as its CHALLENGE proved them) that
    hardware profile `profile_id` was made on."""

    profile_id: int
    key_id: str
    unique_id: str

    def refusal(self, identity: DeviceIdentity | None) -> str:
        """Why a controller with this profile's layout must not run on the device that
        proved `identity` ("" when it is the profile's device)."""
        made_on = f"unique id {self.unique_id}, key id {self.key_id}"
        if identity is None:
            return (f"the device on the link has not proved its identity yet: hardware "
                    f"profile {self.profile_id} (made on the device with {made_on}) "
                    "applies only to its own device")
        if (identity.key_id, identity.unique_id) == (self.key_id, self.unique_id):
            return ""
        return (f"the device on the link (unique id {identity.unique_id}, key id "
                f"{identity.key_id}, firmware {identity.firmware!r}) is not the one "
                f"hardware profile {self.profile_id} was made on ({made_on}); run the "
                "bring-up on this device")
