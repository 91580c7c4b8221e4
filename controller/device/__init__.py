"""Hardware behind an interface: the exoskeleton as a source of samples and a sink of
lock commands."""

from controller.device.base import Device, DeviceError, LockCommand, Sample, Status

__all__ = ["Device", "DeviceError", "LockCommand", "Sample", "Status"]
