"""A simulated EMG amplifier on LSL: the simulated wearer's muscles as a lab would record them.

Why: a lab's amplifier (Delsys, Noraxon, ...) reaches ExoStudy as an LSL stream of type
`EMG` beside LabRecorder; the virtual study must exercise exactly that path. The device
simulator calls `EmgTap` once per 100 Hz tick; the tap turns the wearer's hip moments
and the exoskeleton's torques into activation (`controller.sim.muscles`), activation
into 20 samples per channel at 2 kHz (`controller.sim.surface_emg`), and pushes them as
one chunk.

Stream: type `EMG`, 16 channels, nominal 2000 Hz, float32, values in volts (unit "V",
the project's in-memory unit for raw EMG; XDF's meta-data conventions suggest
microvolts, but a consumer reads the unit from the description either way). Channels
0-11 are the six muscles left then right (`controller.sim.muscles.CHANNELS`), 12-15
are spare inputs with no electrode on a muscle (sensor noise and mains only), as a
16-channel amplifier has when a study uses 12: they let quality flags be tested on a
channel known to hold no muscle. The description holds each channel's label, unit, type,
muscle, side and placement, and the montage (placement scheme, electrode type,
inter-electrode distance, reference).

Timestamps follow the tick clock: tick k's last sample is stamped `t0 + k dt` on the LSL
clock (t0 read at the first tick), the others back-dated by the nominal rate (pylsl's
chunk rule). If the caller falls more than 0.25 s behind that schedule, the schedule is
rebased, as the device server does with its own. pylsl is imported only when a tap is
started, so the simulator never loads liblsl without `--emg-lsl`.
"""

from __future__ import annotations

import copy
import math
import socket
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

from controller.device.base import LockCommand, Sample
from controller.sim.muscles import CHANNELS, MuscleModel, channel_label
from controller.sim.participant import VirtualParticipant
from controller.sim.surface_emg import EmgBlock, EmgSettings, SurfaceEmgGenerator

N_CHANNELS = 16
N_SPARE = N_CHANNELS - len(CHANNELS)
SAMPLES_PER_TICK = 20
RESYNC_S = 0.25
#: The spare inputs' activation, appended to the muscles' in a tick.
_SPARE = [0.0] * N_SPARE
#: Sample numbers 1..n within a tick, for spread stamps.
_STEPS = np.arange(1, SAMPLES_PER_TICK + 1)

#: Electrode placement of each muscle: SENIAM's recommendation where SENIAM has the
#: muscle, common practice otherwise (said so). Bipolar Ag/AgCl, 20 mm apart (SENIAM).
PLACEMENT: dict[str, str] = {
    "erector_spinae_lumbar": "SENIAM longissimus: 2 finger widths lateral of the L1 "
                             "spinous process",
    "erector_spinae_thoracic": "not a SENIAM site: 5 cm lateral of the T9 spinous process "
                               "(common practice)",
    "gluteus_maximus": "SENIAM: 50 % on the line from the sacral vertebrae to the greater "
                       "trochanter",
    "biceps_femoris": "SENIAM: 50 % on the line from the ischial tuberosity to the lateral "
                      "epicondyle of the tibia",
    "rectus_abdominis": "not a SENIAM site: 3 cm lateral of the umbilicus (common practice)",
    "rectus_femoris": "SENIAM: 50 % on the line from the anterior superior iliac spine to "
                      "the superior part of the patella",
}
ELECTRODE = "bipolar Ag/AgCl surface electrodes"
INTER_ELECTRODE_MM = 20.0
REFERENCE = "bipolar; common ground electrode on the iliac crest"


@dataclass
class _Stamps:
    """The last timestamp pushed on an outlet (shared with the outlet when it is)."""

    last: float | None = None


#: Shared outlets by stream name: (outlet, its last stamp).
_SHARED: dict[str, tuple[Any, _Stamps]] = {}


class WearerModel(Protocol):
    """What the tap needs from the simulated exoskeleton (`SimulatedExoskeleton`)."""

    dt: float
    participant: VirtualParticipant
    seed: int

    @property
    def finished(self) -> bool:
        """The script has ended."""
        ...

    def tick(self, command: LockCommand | None) -> Sample:
        """Advance one period."""
        ...

    def human_torques(self) -> tuple[float, float]:
        """The wearer's own hip extension moments (Nm) at the last sample."""
        ...

    def true_torques(self) -> tuple[float, float]:
        """The exoskeleton's extension torques (Nm) at the last sample."""
        ...


def server_source_id(server_pid: int) -> str:
    """The LSL source id of the amplifier a server's in-process simulator publishes
    (`server_pid`: the server process, the worker's parent). Unique on the machine, and
    known to the server before its worker starts: a virtual study subscribes its own
    simulator by it, never another process's stream of the same name."""
    return f"exostudy-simemg-server-{server_pid}"


def channel_labels() -> list[str]:
    """The 16 channel labels, in stream order."""
    return [channel_label(m, s) for m, s in CHANNELS] + [
        f"spare_{i + 1}" for i in range(N_SPARE)]


@dataclass
class TapStats:
    """What the tap did (for logs and tests)."""

    ticks: int = 0
    samples_pushed: int = 0
    onsets: int = 0
    resyncs: int = 0


class EmgTap:
    """Wraps the simulated exoskeleton: every tick also produces and publishes EMG.

    Behaves as the model it wraps towards the device server (`dt`, `finished`, `tick`,
    `warm_up`). `publish=False` keeps the EMG in memory only (`blocks`), for tests and
    batch use without LSL.
    """

    def __init__(
        self, model: WearerModel, name: str = "ExoStudy-SimEMG", source_id: str | None = None,
        settings: EmgSettings | None = None, publish: bool = True, keep: bool = False,
        stamping: Literal["schedule", "spread"] = "schedule",
        only_when_consumed: bool = False, shared: bool = False,
    ) -> None:
        self.model = model
        self.dt = model.dt
        self.name = name
        self.source_id = source_id or f"exostudy-simemg-{socket.gethostname()}-{model.seed}"
        self.muscles = MuscleModel.for_participant(model.participant)
        self.generator = SurfaceEmgGenerator(N_CHANNELS, model.seed, settings, SAMPLES_PER_TICK)
        self.publish = publish
        self.keep = keep
        #: "schedule": tick k's last sample at t0 + k dt (a device with its own clock);
        #: "spread": each tick's samples spread evenly up to the instant the tick is
        #: produced, on the clock its reader stamps the tick with (the in-process
        #: simulator; sped up, the stamps are closer than the nominal period, and the
        #: recording's rate check says so).
        self.stamping = stamping
        #: Generate nothing while no inlet listens (a simulator with the amplifier
        #: switched on but nobody recording costs nothing).
        self.only_when_consumed = only_when_consumed
        #: One outlet per name and process, kept when the tap is closed: a simulator
        #: that swaps its wearer (a new tap) goes on publishing the same stream, as one
        #: amplifier does for one session, so the recording does not restart.
        self.shared = shared
        self._stamps = _Stamps()
        self.blocks: list[EmgBlock] = []
        self.stats = TapStats()
        self._outlet: Any = None
        self._clock: Any = None
        self._t0: float | None = None
        self._activity: str | None = None

    @property
    def finished(self) -> bool:
        """The wrapped model's script has ended."""
        return self.model.finished

    def warm_up(self) -> None:
        """Pay one-time costs before the first tick, on copies (the outlet is never copied)."""
        hook = getattr(self.model, "warm_up", None)
        if callable(hook):
            hook()
        else:
            try:
                copy.deepcopy(self.model).tick(None)
            except Exception:  # a model that cannot be copied just starts cold
                pass
        copy.deepcopy(self.generator).push(np.zeros((1, N_CHANNELS)))

    def start(self) -> None:
        """Open the LSL outlet (nothing when not publishing)."""
        if not self.publish or self._outlet is not None:
            return
        import pylsl

        if self.shared and self.name in _SHARED:
            self._outlet, self._stamps = _SHARED[self.name]
            self._clock = pylsl.local_clock
            return
        info = pylsl.StreamInfo(self.name, "EMG", N_CHANNELS, 1.0 / self.dt * SAMPLES_PER_TICK,
                                pylsl.cf_float32, self.source_id)
        desc = info.desc()
        acq = desc.append_child("acquisition")
        acq.append_child_value("manufacturer", "ExoStudy")
        acq.append_child_value("model", "simulated EMG amplifier (controller.sim.emg_amplifier)")
        acq.append_child_value("participant_seed", str(self.model.seed))
        chans = desc.append_child("channels")
        montage = desc.append_child("montage")
        montage.append_child_value("placement_scheme", "SENIAM where available")
        montage.append_child_value("electrode_type", ELECTRODE)
        montage.append_child_value("inter_electrode_distance_mm", f"{INTER_ELECTRODE_MM:g}")
        montage.append_child_value("reference", REFERENCE)
        for i, label in enumerate(channel_labels()):
            ch = chans.append_child("channel")
            ch.append_child_value("label", label)
            ch.append_child_value("unit", "V")
            ch.append_child_value("type", "EMG")
            entry = montage.append_child("channel")
            entry.append_child_value("label", label)
            if i < len(CHANNELS):
                muscle, side = CHANNELS[i]
                for node in (ch, entry):
                    node.append_child_value("muscle", muscle)
                    node.append_child_value("side", side)
                entry.append_child_value("placement", PLACEMENT[muscle])
            else:
                entry.append_child_value("muscle", "none")
                entry.append_child_value("placement", "spare input, no electrode on a muscle")
        # A shared (in-process, possibly sped-up) outlet keeps LSL's default 6 min for a
        # consumer that falls behind for a while.
        self._outlet = pylsl.StreamOutlet(info, chunk_size=SAMPLES_PER_TICK,
                                          max_buffered=360 if self.shared else 60)
        self._clock = pylsl.local_clock
        if self.shared:
            _SHARED[self.name] = (self._outlet, self._stamps)

    def close(self) -> None:
        """Close the outlet (consumers see the stream end)."""
        self._outlet = None

    def tick(self, command: LockCommand | None) -> Sample:
        """Advance the wrapped model one tick, then generate and publish its EMG."""
        sample = self.model.tick(command)
        self.emit(sample)
        return sample

    def activation(self) -> np.ndarray:
        """Activation (16,) of the last tick: 12 muscles, then 0 on the spare inputs."""
        act = self.muscles.tick_activation(self.model.human_torques(), self.model.true_torques())
        return np.array(act + _SPARE)

    def emit(self, sample: Sample, late_s: float = 0.0) -> EmgBlock | None:
        """Generate the EMG of the tick that ended at `sample` and push it (None: not
        generated, nobody listens and `only_when_consumed`). `late_s`: how long after
        the tick was due it is emitted (a paced device's late reader takes waiting ticks
        at once); spread stamps end at the due instant, so a burst of late ticks keeps
        the sample clock's spacing instead of looking like lost samples."""
        activity = sample.truth.activity if sample.truth is not None else None
        if (self.only_when_consumed and self._outlet is not None
                and not self._outlet.have_consumers()):
            self._activity = activity
            self._stamps.last = None
            return None
        if self._activity is not None and activity != self._activity:
            self.generator.onset()  # a new movement: a motion artefact
            self.stats.onsets += 1
        self._activity = activity
        block = self.generator.push(self.activation())
        self.stats.ticks += 1
        if self.keep:
            self.blocks.append(block)
        if self._outlet is not None and block.samples.shape[0]:
            if self.stamping == "spread":
                self._push_spread(block, max(0.0, late_s))
            else:
                self._push(block, self._stamp(sample.seq))
        return block

    def _push_spread(self, block: EmgBlock, late_s: float = 0.0) -> None:
        """The tick's samples evenly between the previous tick's last stamp and now
        (nominal spacing for the first tick), so stamps never go back and each tick's
        samples carry the instant its reader stamps the tick with."""
        n = block.samples.shape[0]
        now = float(self._clock()) - late_s
        period = 1.0 / self.generator.settings.fs
        prev = self._stamps.last if self._stamps.last is not None else now - n * period
        last = max(now, prev + n * 1e-7)
        steps = _STEPS if n == SAMPLES_PER_TICK else np.arange(1, n + 1)
        stamps = prev + (last - prev) * steps / n
        self._outlet.push_chunk(block.samples.astype(np.float32), stamps.tolist())
        self._stamps.last = last
        self.stats.samples_pushed += n

    def _push(self, block: EmgBlock, last: float) -> None:
        """One chunk stamped at its last sample; with samples missing (a dropped-samples
        fault) each sample gets its own stamp, so the gap shows in the timestamps."""
        data = block.samples.astype(np.float32)
        fs = self.generator.settings.fs
        end_t = (self.generator.samples_generated - 1) / fs
        if data.shape[0] == SAMPLES_PER_TICK and math.isclose(float(block.t[-1]), end_t):
            self._outlet.push_chunk(data, last)
        else:
            for row, t in zip(data, block.t, strict=True):
                self._outlet.push_sample(row, last - (end_t - float(t)))
        self.stats.samples_pushed += data.shape[0]

    def _stamp(self, k: int) -> float:
        """LSL time of tick k's last sample on the tick schedule, rebased after a stall."""
        now = float(self._clock())
        if self._t0 is None or now - (self._t0 + k * self.dt) > RESYNC_S:
            if self._t0 is not None:
                self.stats.resyncs += 1
            self._t0 = now - k * self.dt
        return self._t0 + k * self.dt


def tap(model: Any, name: str = "ExoStudy-SimEMG") -> EmgTap:
    """The device server's hook: wrap `model` and open the outlet."""
    t = EmgTap(model, name=name)
    t.start()
    return t

