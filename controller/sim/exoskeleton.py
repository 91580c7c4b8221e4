"""The simulated exoskeleton on a simulated wearer: lock commands in, samples out, 100 Hz.

It joins a participant, a script realised as a trajectory (see `scripts`), the
exoskeleton's offset on the body and the plant (`plant`). It knows no time but its own
tick count, so it runs as fast as the caller asks; `SimulatedDevice` paces it at 100 Hz
and the UDP device server puts it behind the wire protocol.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from controller.device.base import SAMPLE_PERIOD_S, GroundTruth, LockCommand, Sample
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.activity_kinds import ACTIVITIES
from controller.sim.participant import VirtualParticipant
from controller.sim.plant import ExoPlant
from controller.sim.scripts import Trajectory, get_script, realise


class _Chunk:
    """One repetition of the script, prepared as plain Python lists for fast ticking."""

    def __init__(
        self, traj: Trajectory, participant: VirtualParticipant, seed: int, rep: int
    ) -> None:
        self.traj = traj
        self.n = traj.n
        link = traj.theta + participant.encoder_offset(traj.t)
        self.link_left: list[float] = link[:, 0].tolist()
        self.link_right: list[float] = link[:, 1].tolist()
        rng = np.random.default_rng(np.random.SeedSequence([0x401_5E, int(seed), int(rep)]))
        #: Standard normal draws for the four encoders, a row per sample.
        self.noise: list[list[float]] = rng.standard_normal((self.n, 4)).tolist()
        self.activity: list[str] = [ACTIVITIES[c] for c in traj.activity.tolist()]
        self.lift: list[int] = traj.lift.tolist()
        self.progress: list[float] = traj.progress.tolist()


class SimulatedExoskeleton:
    """A virtual participant wearing the exoskeleton and following a script.

    `tick(command)` applies the lock command (None keeps the previous one) to the step
    that ends at the returned sample; sample `k` has `t = k * dt`. Without `loop`,
    `finished` turns True with the script's last sample and further ticks hold that
    final standing posture. With `loop`, the script restarts with new repetitions
    (new draws of every duration and depth); lift indices keep counting. `duration` is
    the length of one repetition in seconds.
    """

    dt: float = SAMPLE_PERIOD_S

    def __init__(
        self,
        seed: int = 0,
        script: str = "paper-evaluation",
        layout: EncoderLayout = DEFAULT_LAYOUT,
        precompression_pct: float = 25.0,
        participant: VirtualParticipant | None = None,
        loop: bool = False,
    ) -> None:
        self.script = get_script(script)
        self.seed = int(seed)
        self.participant = (
            participant if participant is not None else VirtualParticipant.from_seed(seed)
        )
        self.loop = loop
        self.layout = layout
        self.precompression_pct = precompression_pct
        self.plant = ExoPlant(precompression_pct, layout)
        self._rep = 0
        self._lift_offset = 0
        self._chunk = self._make_chunk(0, 0.0, 0)
        self._start = 0  # sample index of the chunk's first sample
        self.duration = self._chunk.traj.duration
        self.finished = False
        #: False for the "no exoskeleton" baseline: the wearer moves as scripted, the
        #: springs never engage and the wearer gets no torque (`true_torques` is 0).
        self.worn = True
        self._k = 0
        self._lock = (False, False)
        self._i = 0  # index in the chunk of the last sample produced
        self.plant.reset(self._chunk.link_left[0], self._chunk.link_right[0])
        # A looping simulator prepares its next repetition while this one plays: building
        # one takes tens of milliseconds, which inside a tick would stall a 100 Hz stream.
        self._next: Future[_Chunk] | None = None
        self._pool: ThreadPoolExecutor | None = None
        if loop:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sim-prefetch")
            self._prefetch()

    def _prefetch(self) -> None:
        if self._pool is None:
            return
        rep = self._rep + 1
        t0 = (self._start + self._chunk.n) * SAMPLE_PERIOD_S
        offset = self._lift_offset + self._chunk.traj.n_lifts
        self._next = self._pool.submit(self._make_chunk, rep, t0, offset)

    def _make_chunk(self, rep: int, t0: float, lift_offset: int) -> _Chunk:
        traj = realise(self.script, self.participant, self.seed, rep, t0, lift_offset)
        return _Chunk(traj, self.participant, self.seed, rep)

    @property
    def seq(self) -> int:
        """Sequence number the next sample will carry."""
        return self._k

    @property
    def trajectory(self) -> Trajectory:
        """The repetition being played (true angles, human moments, ground truth)."""
        return self._chunk.traj

    def tick(self, command: LockCommand | None) -> Sample:
        """Apply `command` (None: keep the previous one) and produce the next sample."""
        if command is not None:
            self._lock = (bool(command.lock_left), bool(command.lock_right))
        k = self._k
        i = k - self._start
        chunk = self._chunk
        if i >= chunk.n:
            if self.loop:
                self._rep += 1
                self._lift_offset += chunk.traj.n_lifts
                if self._next is not None:
                    self._chunk = chunk = self._next.result()
                else:
                    self._chunk = chunk = self._make_chunk(
                        self._rep, k * SAMPLE_PERIOD_S, self._lift_offset)
                self._start = k
                i = 0
                self._prefetch()
            else:
                i = chunk.n - 1
        self._i = i
        plant = self.plant
        left, right = self._lock if self.worn else (False, False)
        status = plant.step(left, right, chunk.link_left[i], chunk.link_right[i])
        counts = plant.counts(chunk.noise[(k - self._start) % chunk.n])
        truth = GroundTruth(chunk.activity[i], chunk.lift[i], chunk.progress[i])
        self._k = k + 1
        if not self.loop and self._k - self._start >= chunk.n:
            self.finished = True
        return Sample(seq=k, t=k * SAMPLE_PERIOD_S, counts=counts, status=status, truth=truth)

    def true_torques(self) -> tuple[float, float]:
        """Exoskeleton extension torque (Nm), left and right, at the last sample (none
        when not worn)."""
        return self.plant.torques() if self.worn else (0.0, 0.0)

    def true_angles(self) -> tuple[float, float]:
        """The wearer's true hip flexion (rad), left and right, at the last sample."""
        th = self._chunk.traj.theta[self._i]
        return float(th[0]), float(th[1])

    def human_torques(self) -> tuple[float, float]:
        """The wearer's own hip extension moment (Nm) without the exoskeleton."""
        tq = self._chunk.traj.torque[self._i]
        return float(tq[0]), float(tq[1])

    def alphas(self) -> tuple[float, float]:
        """Spring deflection (rad), left and right."""
        return self.plant.left.alpha, self.plant.right.alpha

    def __repr__(self) -> str:
        return (
            f"SimulatedExoskeleton(seed={self.seed}, script={self.script.name!r}, "
            f"loop={self.loop}, t={self._k * SAMPLE_PERIOD_S:.2f}, duration={self.duration:.1f})"
        )

