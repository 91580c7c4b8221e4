"""Hip velocities for the E-UMC and PEC: a constant-velocity Kalman filter per hip.

Model (docs/controller-design.md, "E-UMC and PEC"), per hip, state `x = [q, omega]`:

- `x_k = F x_{k-1} + G a_k` with `F = [[1, dt], [0, 1]]`, `G = [dt^2/2, dt]` and a white
  acceleration `a_k ~ N(0, sigma_a^2)` held over each sample (the discrete white-noise
  acceleration model), so `Q = sigma_a^2 G G^T`;
- `z_k = q_k + v_k` with `v_k ~ N(0, sigma_z^2)`, `sigma_z = 1.05e-3` rad.

Both hips share the same model and are sampled together, so their covariances (and
gains) are identical: the filter propagates one covariance and two states, in plain
scalar arithmetic on a preallocated state array (`kalman_step`, compiled, no allocation).

Initialisation: the first finite sample sets `q`, with `omega = 0`, position variance
`sigma_z^2` and velocity variance `init_omega_std^2` (default (1 rad/s)^2). A sample
with a NaN angle on either side is skipped as a measurement: the filter only predicts.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from controller.device.base import SAMPLE_PERIOD_S

FloatArray = npt.NDArray[np.float64]

#: Encoder-derived measurement noise of a hip angle, rad.
MEAS_STD = 1.05e-3
#: Default white-acceleration noise, rad/s^2 (docs/controller-design.md: 10 to 20).
ACCEL_STD = 15.0


# Filter state, a float64 array so the compiled tick can own it: initialised flag, both
# hips' (q, omega), the shared covariance and the last gain.
_INIT, _QL, _WL, _QR, _WR, _P00, _P01, _P11, _K0, _K1 = range(10)
N_STATE = 10
# Constants: dt, the process noise Q (q00, q01, q11), R, and the initial velocity variance.
_DT, _Q00, _Q01, _Q11, _R, _W_VAR0 = range(6)
N_PARAMS = 6


@njit("UniTuple(float64, 2)(float64[::1], float64[::1], float64, float64)", cache=True,
      nogil=True)
def kalman_step(
    st: FloatArray, prm: FloatArray, q_left: float, q_right: float
) -> tuple[float, float]:
    """Filter one sample of both hips in place; (omega_left, omega_right) in rad/s.

    The one implementation of the filter: `HipVelocityFilter` and the compiled control
    tick (`controller.kernel.tick`) both call it. Plain scalar arithmetic, in the
    order of the equations in the module docstring.
    """
    usable = not (math.isnan(q_left) or math.isnan(q_right))
    if st[_INIT] == 0.0:
        if not usable:
            return math.nan, math.nan
        st[_INIT] = 1.0
        st[_QL] = q_left
        st[_QR] = q_right
        st[_WL] = 0.0
        st[_WR] = 0.0
        st[_P00] = prm[_R]
        st[_P01] = 0.0
        st[_P11] = prm[_W_VAR0]
        return 0.0, 0.0
    dt = prm[_DT]
    # Predict.
    p01 = st[_P01] + dt * st[_P11]
    p00 = st[_P00] + dt * (st[_P01] + p01) + prm[_Q00]
    p01 += prm[_Q01]
    p11 = st[_P11] + prm[_Q11]
    ql = st[_QL] + dt * st[_WL]
    qr = st[_QR] + dt * st[_WR]
    if usable:
        s = p00 + prm[_R]
        k0 = p00 / s
        k1 = p01 / s
        el = q_left - ql
        er = q_right - qr
        ql += k0 * el
        qr += k0 * er
        st[_WL] += k1 * el
        st[_WR] += k1 * er
        p11 -= k1 * p01
        p00 *= 1.0 - k0
        p01 *= 1.0 - k0
        st[_K0] = k0
        st[_K1] = k1
    st[_QL] = ql
    st[_QR] = qr
    st[_P00] = p00
    st[_P01] = p01
    st[_P11] = p11
    return st[_WL], st[_WR]


class HipVelocityFilter:
    """Two constant-velocity Kalman filters (left, right hip) with one shared covariance.

    `state` and `constants` are the arrays `kalman_step` works on; the compiled control
    tick holds a pair of its own built by `arrays()`.
    """

    def __init__(
        self,
        accel_std: float = ACCEL_STD,
        meas_std: float = MEAS_STD,
        dt: float = SAMPLE_PERIOD_S,
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
        self.constants = np.array([
            dt, s2 * dt**4 / 4.0, s2 * dt**3 / 2.0, s2 * dt * dt, meas_std * meas_std,
            init_omega_std * init_omega_std,
        ])
        self.state = np.zeros(N_STATE)

    def reset(self) -> None:
        """Forget the state; the next finite sample re-initialises it."""
        self.state[:] = 0.0

    @property
    def initialised(self) -> bool:
        """True once a finite sample has been filtered."""
        return bool(self.state[_INIT])

    @property
    def gain(self) -> tuple[float, float]:
        """Kalman gain (position, velocity) of the last update."""
        return float(self.state[_K0]), float(self.state[_K1])

    @property
    def covariance(self) -> tuple[float, float, float]:
        """Posterior covariance (p_qq, p_qw, p_ww), shared by both hips."""
        st = self.state
        return float(st[_P00]), float(st[_P01]), float(st[_P11])

    @property
    def angles(self) -> tuple[float, float]:
        """Filtered (left, right) hip angles, rad."""
        return float(self.state[_QL]), float(self.state[_QR])

    def step(self, q_left: float, q_right: float) -> tuple[float, float]:
        """Filter one sample of both hips; return (omega_left, omega_right) in rad/s.

        Before the first finite sample the velocities are NaN.
        """
        return kalman_step(self.state, self.constants, float(q_left), float(q_right))

