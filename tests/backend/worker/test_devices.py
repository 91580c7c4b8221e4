"""The worker's device factory: the in-process simulator's EMG stream is named after the
server (the worker's parent), so the server subscribes its own simulator by source id
and never another one on the same machine."""

from __future__ import annotations

import os

from backend.worker.devices import make_device
from backend.worker.messages import WorkerConfig
from controller.sim.emg_amplifier import server_source_id
from controller.sim.simulated_device import SimulatedDevice


def test_the_simulated_amplifier_carries_the_servers_source_id() -> None:
    server = os.getpid() + 7  # the worker's parent is the fork server, not the server
    dev = make_device(WorkerConfig(device_kind="sim", device_emg_lsl=True), server)
    assert isinstance(dev, SimulatedDevice) and dev.emg is not None
    assert dev.emg.source_id == server_source_id(server)
    assert server_source_id(server) != server_source_id(server + 1)
    assert make_device(WorkerConfig(device_kind="sim"), server).emg is None  # type: ignore[attr-defined]
