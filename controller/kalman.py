"""Hip velocities for the E-UMC and PEC: a constant-velocity Kalman filter per hip.

Model (controller.md, "E-UMC and PEC"), per hip, state `x = [q, omega]`:

- `x_k = F x_{k-1} + G a_k` with `F = [[1, dt], [0, 1]]`, `G = [dt^2/2, dt]` and a white
  acceleration `a_k ~ N(0, sigma_a^2)` held over each sample (the discrete white-noise
  acceleration model), so `Q = sigma_a^2 G G^T`;
- `z_k = q_k + v_k` with `v_k ~ N(0, sigma_z^2)`, `sigma_z = 1.05e-3` rad.

Both hips share the same model and are sampled together, so their covariances (and
gains) are identical: the class propagates one covariance and two states, in plain
scalar arithmetic (no numpy, no allocation per step).

Initialisation: the first finite sample sets `q`, with `omega = 0`, position variance
`sigma_z^2` and velocity variance `init_omega_std^2` (default (1 rad/s)^2). A sample
with a NaN angle on either side is skipped as a measurement: the filter only predicts.
"""

from __future__ import annotations

import math

#: Encoder-derived measurement noise of a hip angle, rad.
MEAS_STD = 1.05e-3
#: Default white-acceleration noise, rad/s^2 (controller.md: 10 to 20).
ACCEL_STD = 15.0
DT = 0.01


class HipVelocityFilter:
    """Two constant-velocity Kalman filters (left, right hip) with one shared covariance."""

    def __init__(
        self,
        accel_std: float = ACCEL_STD,
        meas_std: float = MEAS_STD,
        dt: float = DT,
        init_omega_std: float = 1.0,
    ) -> None:
        """Args: accel_std rad/s^2, meas_std rad, dt s, init_omega_std rad/s (all > 0)."""
        for name, v in (
            ("accel_std", accel_std), ("meas_std", meas_std), ("dt", dt),
            ("init_omega_std", init_omega_std),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        self.accel_std = accel_std
        self.meas_std = meas_std
        self.dt = dt
        self.init_omega_std = init_omega_std
        s2 = accel_std * accel_std
        self._q00 = s2 * dt**4 / 4.0
        self._q01 = s2 * dt**3 / 2.0
        self._q11 = s2 * dt * dt
        self._r = meas_std * meas_std
        self.reset()

    def reset(self) -> None:
        """Forget the state; the next finite sample re-initialises it."""
        self._init = False
        self._ql = self._wl = self._qr = self._wr = 0.0
        self._p00 = self._p01 = self._p11 = 0.0
        self._k0 = self._k1 = 0.0

    @property
    def initialised(self) -> bool:
        """True once a finite sample has been filtered."""
        return self._init

    @property
    def gain(self) -> tuple[float, float]:
        """Kalman gain (position, velocity) of the last update."""
        return self._k0, self._k1

    @property
    def covariance(self) -> tuple[float, float, float]:
        """Posterior covariance (p_qq, p_qw, p_ww), shared by both hips."""
        return self._p00, self._p01, self._p11

    @property
    def angles(self) -> tuple[float, float]:
        """Filtered (left, right) hip angles, rad."""
        return self._ql, self._qr

    def step(self, q_left: float, q_right: float) -> tuple[float, float]:
        """Filter one sample of both hips; return (omega_left, omega_right) in rad/s.

        Before the first finite sample the velocities are NaN.
        """
        usable = not (math.isnan(q_left) or math.isnan(q_right))
        if not self._init:
            if not usable:
                return math.nan, math.nan
            self._init = True
            self._ql, self._qr = q_left, q_right
            self._wl = self._wr = 0.0
            self._p00 = self._r
            self._p01 = 0.0
            self._p11 = self.init_omega_std * self.init_omega_std
            return 0.0, 0.0
        dt = self.dt
        # Predict.
        p01 = self._p01 + dt * self._p11
        p00 = self._p00 + dt * (self._p01 + p01) + self._q00
        p01 += self._q01
        p11 = self._p11 + self._q11
        ql = self._ql + dt * self._wl
        qr = self._qr + dt * self._wr
        if usable:
            s = p00 + self._r
            k0 = p00 / s
            k1 = p01 / s
            el = q_left - ql
            er = q_right - qr
            ql += k0 * el
            qr += k0 * er
            self._wl += k1 * el
            self._wr += k1 * er
            p11 -= k1 * p01
            p00 *= 1.0 - k0
            p01 *= 1.0 - k0
            self._k0, self._k1 = k0, k1
        self._ql, self._qr = ql, qr
        self._p00, self._p01, self._p11 = p00, p01, p11
        return self._wl, self._wr


class VelocityTrigger:
    """The paper's trigger: both hips flexing at or above `threshold` rad/s (eq. 14)."""

    def __init__(self, threshold: float = 1.0) -> None:
        """Args: threshold in rad/s, finite."""
        if not math.isfinite(threshold):
            raise ValueError(f"threshold must be finite, got {threshold!r}")
        self.threshold = threshold

    def __call__(self, omega_left: float, omega_right: float) -> bool:
        """True iff `omega_left >= threshold` and `omega_right >= threshold` (NaN: False)."""
        return omega_left >= self.threshold and omega_right >= self.threshold
