"""A controller bound to one device (its hardware profile's encoder layout) never locks
another: real device processes told apart by `--device-id`, the real worker process, and
a man-in-the-middle that holds the key and reads every COMMAND on the wire.

Device A is the one the profile was made on, device B another exoskeleton on the same
link key. A start on B is refused; a swap from A to B under a running controller stops
it, released, with no lock sent to B."""

from __future__ import annotations

from pathlib import Path

from backend.worker.device_gate import DeviceGate
from backend.worker.messages import SetController
from controller.controllers.spec import ControllerSpec
from controller.device.auth import key_id, load_or_create_key
from controller.device.protocol import CommandPacket, ProtocolError, decode_frame
from tests.faults.device_rig import Proxy, Worker, device_process, locked_ticks
from tests.polling import free_udp_port, wait_for

DEVICE_A = "a1" * 16
DEVICE_B = "b2" * 16


def _lock_commands(datagrams: list[bytes], key: bytes, to: int | None = None) -> int:
    """COMMANDs on the wire that ask for a solenoid (addressed to device session `to`
    only, if given)."""
    n = 0
    for d in list(datagrams):
        try:
            frame = decode_frame(d, key)
        except ProtocolError:
            continue
        packet = frame.packet
        if isinstance(packet, CommandPacket) and (packet.lock_left or packet.lock_right) \
                and (to is None or frame.receiver == to):
            n += 1
    return n


def _squatted(worker: Worker, since: int) -> bool:
    """The wearer flexed 30 degrees in a squat since tick `since`, for at least three
    seconds of ticks (something a controller would lock on)."""
    ticks = worker.ticks()[since:]
    return len(ticks) >= 300 and any(r.q_raw_left > 0.5 and r.truth_activity == "squat"
                                     for r in ticks)


def _session(worker: Worker) -> int:
    st = worker.sup.state.status
    assert st is not None and st.identity is not None
    return st.identity.device_session


def _identity(worker: Worker) -> str | None:
    st = worker.sup.state.status
    return None if st is None or st.identity is None else st.identity.unique_id


def _device_alive(worker: Worker) -> bool:
    """The worker's latest status says a sample came within the last 0.5 s."""
    st = worker.sup.state.status
    return st is not None and st.device.alive


def _start(worker: Worker, spec: ControllerSpec, gate: DeviceGate) -> None:
    assert worker.sup._cmd is not None
    worker.sup._cmd.send(SetController(spec, request_id=7, device=gate))


def test_a_controller_bound_to_another_device_is_not_started(
        tmp_path: Path, device_implementation: str) -> None:
    key_file = tmp_path / "device.key"
    key = load_or_create_key(key_file)
    gate_a = DeviceGate(1, key_id(key), DEVICE_A)
    port = free_udp_port()
    with device_process(port, key_file, "squat-sequence", extra=("--device-id", DEVICE_B),
                        implementation=device_implementation), \
            Proxy(port) as proxy, Worker(proxy.port, key_file) as worker:
        wait_for(lambda: _identity(worker) == DEVICE_B, 90, "device B to prove its identity")
        start = len(worker.ticks())
        _start(worker, ControllerSpec("pec"), gate_a)
        wait_for(lambda: any("not started" in e for e in worker.sup.state.errors), 30,
                 "the worker to refuse the controller")
        wait_for(lambda: _squatted(worker, start), 90, "a squat under `none`")
        after = worker.ticks()[start:]
        errors = list(worker.sup.state.errors)
        runs = [r.controller for r in worker.runs]
        wire_locks = _lock_commands(proxy.to_device, key)
    refusal = next(e for e in errors if "not started" in e)
    assert DEVICE_A in refusal and DEVICE_B in refusal  # which device is which
    assert runs == ["none"]  # the PEC never ran
    assert locked_ticks(after) == 0 and wire_locks == 0


def test_a_device_swapped_under_a_running_controller_gets_no_lock(
        tmp_path: Path, device_implementation: str) -> None:
    key_file = tmp_path / "device.key"
    key = load_or_create_key(key_file)
    gate_a = DeviceGate(1, key_id(key), DEVICE_A)
    port = free_udp_port()
    with Proxy(port) as proxy, Worker(proxy.port, key_file) as worker:
        with device_process(port, key_file, "squat-sequence",
                            extra=("--device-id", DEVICE_A),
                            implementation=device_implementation):
            wait_for(lambda: _identity(worker) == DEVICE_A, 90,
                     "device A to prove its identity")
            _start(worker, ControllerSpec("pec"), gate_a)
            # On its own device the bound controller runs and locks (the control case).
            wait_for(lambda: locked_ticks(worker.ticks()) > 20, 90, "the PEC to lock on A")
            session_a = _session(worker)
        # Device A is gone (its process stopped); device B boots on the same address,
        # once the worker has reported A silent: its status goes out after every tick
        # it had queued, so A's last ticks (the PEC may have locked them) are all in
        # and none of them is counted as B's.
        wait_for(lambda: not _device_alive(worker), 10, "the worker to report A silent")
        ticks_at = len(worker.ticks())
        with device_process(port, key_file, "squat-sequence", seed=2,
                            extra=("--device-id", DEVICE_B),
                            implementation=device_implementation):
            wait_for(lambda: _identity(worker) == DEVICE_B, 90, "device B to join")
            wait_for(lambda: any("stopped, released" in e for e in worker.sup.state.errors),
                     30, "the worker to stop the controller")
            wait_for(lambda: _squatted(worker, ticks_at), 90, "a squat on B")
            on_b = worker.ticks()[ticks_at:]
            errors = list(worker.sup.state.errors)
            runs = [r.controller for r in worker.runs]
            session_b = _session(worker)
            wire_locks = _lock_commands(proxy.to_device, key, to=session_b)
    stopped = next(e for e in errors if "stopped, released" in e)
    assert DEVICE_A in stopped and DEVICE_B in stopped
    assert runs == ["none", "pec", "none"] and session_b != session_a
    assert locked_ticks(on_b) == 0 and wire_locks == 0
