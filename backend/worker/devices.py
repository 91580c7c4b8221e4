"""Build the device named by the worker configuration (inside the worker process)."""

from __future__ import annotations

from backend.worker.messages import WorkerConfig
from controller.device.base import Device


def make_device(config: WorkerConfig, server_pid: int) -> Device:
    """The configured device; imports lazily so the worker only loads what it uses.
    `server_pid` names the server whose EMG inlet subscribes to the simulator's stream."""
    if config.device_kind == "sim":
        from controller.sim.simulated_device import SimulatedDevice

        source_id = None
        if config.device_emg_lsl:
            # Only then: the EMG simulator's imports (SciPy's signal and statistics)
            # cost a worker without EMG more than a second of CPU at every start.
            from controller.sim.emg_amplifier import server_source_id

            # The server subscribes its own simulator by this id.
            source_id = server_source_id(server_pid)
        return SimulatedDevice(
            seed=config.device_seed,
            script=config.device_script,
            realtime=True,
            loop=True,
            precompression_pct=config.precompression_pct,
            speed=config.device_speed,
            emg_lsl=config.device_emg_lsl,
            emg_source_id=source_id,
        )
    if config.device_kind == "udp":
        from pathlib import Path

        from controller.device.auth import load_key
        from controller.device.udp import UdpDevice

        if not config.device_key_file:
            raise ValueError("the UDP device needs its link key file (device_key_file)")
        return UdpDevice(device_host=config.device_host, device_port=config.device_port,
                         key=load_key(Path(config.device_key_file)))
    raise ValueError(f"unknown device kind {config.device_kind!r}; use 'sim' or 'udp'")
