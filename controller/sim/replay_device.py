"""A device that plays recorded hip angles, for offline replay through the live code path.

The recorded angles drive the simulated mechanism (`controller.sim.plant.ExoPlant`) with
ideal encoders, so the lock commands a controller sends during replay produce the
deflections and torques they would have produced on the exoskeleton ("torques after the
fact" in the paper's evaluation). The angles are used as measured: no noise is added.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from controller.device.base import Device, GroundTruth, LockCommand, Sample
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.plant import EncoderModel, ExoPlant

_NO_NOISE = (0.0, 0.0, 0.0, 0.0)


class ReplayDevice(Device):
    """Serves one sample per `read`, as fast as asked (no pacing)."""

    kind = "replay"

    def __init__(
        self,
        t: NDArray[np.float64],
        q: NDArray[np.float64],
        precompression_pct: float = 25.0,
        layout: EncoderLayout = DEFAULT_LAYOUT,
        activity: list[str] | None = None,
        lift_index: NDArray[np.int64] | None = None,
    ) -> None:
        t = np.asarray(t, dtype=np.float64)
        q = np.asarray(q, dtype=np.float64)
        if t.ndim != 1 or q.shape != (t.size, 2):
            raise ValueError(f"need t (K,) and q (K, 2); got {t.shape} and {q.shape}")
        if t.size == 0:
            raise ValueError("nothing to replay: no samples")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ValueError("sample times must be finite and strictly increasing")
        self.t, self.q = t, q
        self.activity = activity
        self.lift_index = lift_index
        self.plant = ExoPlant(precompression_pct, layout, encoders=EncoderModel.ideal())
        self.layout = layout
        self._k = 0
        self._cmd = (False, False)

    @property
    def finished(self) -> bool:
        """All samples served."""
        return self._k >= self.t.size

    def open(self) -> None:
        """Start at the first sample with both sides unlocked."""
        self._k = 0
        ql, qr = self.q[0]
        self.plant.reset(float(ql) if math.isfinite(ql) else 0.0,
                         float(qr) if math.isfinite(qr) else 0.0)

    def read(self, timeout: float) -> Sample | None:
        """The next recorded sample, through the mechanism; None at the end."""
        k = self._k
        if k >= self.t.size:
            return None
        self._k = k + 1
        ql, qr = float(self.q[k, 0]), float(self.q[k, 1])
        truth = None
        if self.activity is not None:
            lift = int(self.lift_index[k]) if self.lift_index is not None else -1
            truth = GroundTruth(self.activity[k], lift)
        if not (math.isfinite(ql) and math.isfinite(qr)):
            # A gap in the recording: an impossible count marks the sample as bad.
            return Sample(seq=k, t=float(self.t[k]), counts=(0, 0, 1 << 15, 0), truth=truth)
        status = self.plant.step(self._cmd[0], self._cmd[1], ql, qr)
        return Sample(seq=k, t=float(self.t[k]), counts=self.plant.counts(_NO_NOISE),
                      status=status, truth=truth)

    def send(self, command: LockCommand) -> None:
        """Applied at the next sample."""
        self._cmd = (command.lock_left, command.lock_right)

    def release(self) -> None:
        """Drop the solenoid commands."""
        self._cmd = (False, False)

    def close(self) -> None:
        """Nothing to disconnect."""
        self.release()
