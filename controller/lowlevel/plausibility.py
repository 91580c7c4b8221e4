"""Plausibility of a sample: what a human hip in this exoskeleton can and cannot do.

A sample can be well formed (four 14-bit counts, a finite time, no fault bit) and still
be impossible: a single-sample glitch of one encoder, a stuck or repeated packet, a
device that restarted, a device that sends ten times too fast. The control tick
(`controller.kernel.check.check_sample`, compiled) checks every sample against the bounds
below before any controller sees it; a sample that fails is flagged (`TickFlag.IMPLAUSIBLE`
and the reason bits of `Plausibility`), never enters the filters, and commands no new
lock. The reasoning and the literature are in `docs/plausibility.md`.

Bounds (assumptions stated; none tuned to a result):

- `HIP_VELOCITY_MAX` 20 rad/s (1150 deg/s): reported peak hip flexion velocities in the
  fastest human movements (maximal sprinting, kicking) stay below about 12-15 rad/s;
  lifting and walking stay below 5 rad/s. 20 rad/s leaves a third of margin above the
  fastest, so no real movement is flagged.
- `ANGLE_NOISE_RAD` 1 deg: the AS5048A's noise (0.06 deg RMS) and non-linearity
  (+-0.8 deg, a slow error) allowance added to the jump bound, so an encoder at rest
  cannot fail it.
- Jump bound between the last accepted sample and this one, `dt` apart in device time:
  `HIP_VELOCITY_MAX * dt + ANGLE_NOISE_RAD` (0.21 rad at 10 ms). In this and the
  acceleration bound `dt` counts at most two periods, so a reading that jumped and
  stayed is not let in gradually (as a fast movement); it waits for the resync.
- `HIP_ACCELERATION_MAX` 300 rad/s^2 (an assumption, not a measured human limit): a hip
  going from rest to the fastest human hip velocity (about 12 rad/s) within 40 ms. The
  check: the angle must lie within `HIP_ACCELERATION_MAX * dt^2 + ANGLE_NOISE_RAD`
  (0.047 rad, 2.7 deg, at 10 ms) of where the last two accepted samples were heading
  (their difference is the velocity half a period earlier, hence `dt^2`, not `dt^2/2`).
  A single-sample glitch larger than that is caught on the glitch itself, so it never
  reaches the velocity filter (smaller ones look like, and act as, real motion).
- `MIN_INTERVAL_S` 5 ms: samples come every 10 ms; one less than half a period after the
  last accepted sample is early (a device sending too fast, or a duplicate).
- `RESYNC_S` 0.1 s: after this much device time without an accepted sample, the filters'
  state is stale (a constant-velocity filter would turn the change into a velocity
  spike); they restart from the next sample, which is flagged.
- Hip flexion within `Q_RANGE` (-60 to 160 deg; counts outside are BAD_SAMPLE as before):
  the passive range of the hip is about -30 to 140 deg.
- Spring deflection within `ALPHA_RANGE` (-5 to 100 deg): the mechanism keeps it at 0
  unlocked and at most 93.8 deg at the 22 mm spring limit (P = 0), plus twice the
  encoders' non-linearity and noise.
"""

from __future__ import annotations

import math

HIP_VELOCITY_MAX = 20.0
HIP_ACCELERATION_MAX = 300.0
ANGLE_NOISE_RAD = math.radians(1.0)
MIN_INTERVAL_S = 0.005
RESYNC_S = 0.1
Q_RANGE = (math.radians(-60.0), math.radians(160.0))
ALPHA_RANGE = (math.radians(-5.0), math.radians(100.0))


def course_bound(dt: float) -> float:
    """Largest plausible distance (rad) of a hip angle, `dt` seconds on, from where its
    last velocity was taking it."""
    return HIP_ACCELERATION_MAX * dt * dt + ANGLE_NOISE_RAD
