"""The virtual study's simulator speed-ups, apart from the study itself so that the
command line's help can show them without importing the whole analysis stack."""

from __future__ import annotations

from controller.device.base import MAX_SPEED

#: Requested simulator speed-up during the evaluation trials: the simulator's maximum
#: (`controller.sim.simulated_device.MAX_SPEED`).
#: The worker never runs ahead of what the server stores (it holds a sped-up simulation
#: while ticks queue, `backend.worker.process._hold`), so asking for more than a loaded
#: machine delivers costs nothing and loses nothing; on a quiet 2-core machine 80x gave a
#: median of 6,200 ticks/s. See README "Results and the virtual study".
DEFAULT_SPEED: float = MAX_SPEED
#: Speed-up while demonstrations are recorded: the simulator's maximum too. The wearer
#: starts with the recording (`RecordingIn.simulation`), so no lift is lost at any speed;
#: when a recording started by a second request, 80x cost a lift or two per recording
#: (103 instead of 126 segments in the default study) and collection ran at 30x.
COLLECTION_SPEED: float = MAX_SPEED
