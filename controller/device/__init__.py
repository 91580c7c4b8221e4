"""Hardware behind an interface: the exoskeleton as a source of samples and a sink of
lock commands.

- `base`: the interface (`Device`, `DeviceError`, `LockCommand`, `Sample`, `Status`).
- `protocol`: the wire protocol; `auth`: its authentication; `udp`: the host side.

The package re-exports nothing: import from the module.
"""
