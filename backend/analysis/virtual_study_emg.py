"""A virtual study's muscle activity (`emg`): the EMG study's montage and settings, the
subscription of each session to the simulated amplifier's LSL stream, and the pause
after a sped-up trial until the server's inlet has stored what it produced. Apart from
the trials because only an EMG study does any of it."""

from __future__ import annotations

import os
import time

from backend.analysis.virtual_study_config import (
    EMG_SETTINGS,
    EMG_SPARE,
    EMG_STREAM,
    STALL_S,
    VirtualStudyError,
)
from backend.analysis.virtual_study_driver import Driver, ok
from controller.sim.emg_amplifier import (
    ELECTRODE,
    INTER_ELECTRODE_MM,
    PLACEMENT,
    REFERENCE,
    server_source_id,
)
from controller.sim.muscles import CHANNELS, channel_label


def setup_emg(d: Driver, study_id: int) -> None:
    """The EMG study's montage (the simulated amplifier's 12 muscle channels, SENIAM
    where SENIAM has the muscle) and its processing settings."""
    channels = [{"label": channel_label(m, side), "muscle": m, "side": side,
                 "placement": PLACEMENT[m], "electrode_type": ELECTRODE,
                 "inter_electrode_distance_mm": INTER_ELECTRODE_MM, "reference": REFERENCE}
                for m, side in CHANNELS]
    ok(d.c.request("PUT", f"/api/studies/{study_id}/emg-montage", json_body={
        "placement_scheme": "SENIAM where available", "channels": channels}))
    ok(d.c.request("PUT", f"/api/studies/{study_id}/emg-settings", json_body=EMG_SETTINGS))


def lsl_now() -> float:
    """LSL's clock, which the inlet's `last_time` is read on."""
    # Imported here: pylsl loads liblsl, which only an EMG study needs.
    import pylsl

    return float(pylsl.local_clock())


def drain_emg(d: Driver, session_id: int, sub: int, until: float) -> None:
    """Until the server's inlet has recorded the EMG up to `until` (LSL clock): a sped-up
    trial produces EMG faster than a loaded server stores it, and LSL buffers the rest
    (6 min of samples); the pause after each trial lets the inlet catch up, so nothing
    overflows. Fails only if the inlet makes no progress for `STALL_S`."""
    last, since = None, time.monotonic()
    while True:
        streams = ok(d.c.get(f"/api/sessions/{session_id}/emg-streams"))
        t = next((s.get("last_time") for s in streams if s["id"] == sub), None)
        if t is not None and t >= until:
            return
        if t != last:
            last, since = t, time.monotonic()
        elif time.monotonic() - since > STALL_S:
            raise VirtualStudyError(f"the EMG inlet of session {session_id} made no "
                                    f"progress for {STALL_S:.0f} s")
        time.sleep(0.1)


def subscribe_emg(d: Driver, session_id: int) -> int:
    """Record the simulated amplifier with the session (as an experimenter subscribes
    the lab's amplifier); the subscription's id. The stream appears once the simulator
    runs; a subscription is refused (409) until it is visible. By source id: this
    process is the server, the worker's parent, so the id names this study's simulator
    alone; by name, the inlet could record another simulator on the machine (another
    virtual study, a test), whose samples then stand in for this one's."""
    deadline = time.monotonic() + STALL_S
    while True:
        r = d.c.post(f"/api/sessions/{session_id}/emg-streams",
                     json={"name": EMG_STREAM, "source_id": server_source_id(os.getpid()),
                           "ignore_labels": list(EMG_SPARE)})
        if r.status_code == 201:
            sub = int(r.json()["id"])
            break
        if r.status_code != 409 or time.monotonic() > deadline:
            ok(r, 201)
        time.sleep(0.2)
    # Until the inlet records (its first samples make the recording), so no trial
    # starts before its EMG does.
    while time.monotonic() < deadline:
        streams = ok(d.c.get(f"/api/sessions/{session_id}/emg-streams"))
        if any(s["id"] == sub and s.get("connected") for s in streams):
            return sub
        time.sleep(0.05)
    raise VirtualStudyError(f"the EMG stream of session {session_id} never connected")
