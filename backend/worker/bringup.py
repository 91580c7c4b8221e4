"""Hardware bring-up inside the worker: one handler per command, each owning the device
for its few seconds.

The server judges what the samples mean (`controller.lowlevel.bringup`); the worker only does what
needs the device at 100 Hz: capture raw samples with the solenoids off, drive one
bounded solenoid pulse, go silent and time the device's command watchdog, or stop the
firmware's heartbeat output and time the hardware release. Each handler answers every
sample it reads with a command (the link's keep-alive), except the watchdog test's
silence, and every handler ends with `device.release()` whatever happens, so no path
leaves a solenoid energised. Handlers run only while the
controller is `none` (the server also refuses them during a trial or recording).
"""

from __future__ import annotations

import math
import time

from backend.worker.messages import (
    BringupCapture,
    BringupCommand,
    BringupPulse,
    BringupRelease,
    BringupResult,
    BringupWatchdog,
    RawSample,
)
from controller.device.base import SAMPLE_PERIOD_S, Device, LockCommand, Sample, Status
from controller.device.protocol import WATCHDOG_S
from controller.lowlevel.encoders import EncoderLayout

#: Longest solenoid pulse: the low-level controller's lock hold, 0.3 s, long enough for
#: the pawl to seat (docs/hardware.md); a bring-up pulse never holds longer.
PULSE_MAX_S = 0.3
#: Longest capture a bring-up step may ask for (the loop pauses meanwhile).
CAPTURE_MAX_S = 10.0
#: Samples read with the solenoids off before a pulse, to judge that nothing loads the
#: mechanism (50 ms).
PRECHECK_SAMPLES = 5
#: The device must release within 100-110 ms of the last command (docs/device-protocol.md);
#: the test waits up to this long for the release before it reports a failure.
WATCHDOG_WAIT_S = 0.5
#: The hardware release test waits this long (device clock) after the first sample
#: with HEARTBEAT_STOPPED for DRIVERS_OFF, and as long for HEARTBEAT_STOPPED itself.
RELEASE_WAIT_S = 0.5
#: After the heartbeat resumes, the drivers must be enabled again within this long.
DRIVERS_BACK_WAIT_S = 0.3
#: Samples after a pulse in which the solenoid bit must have cleared.
RELEASE_SAMPLES = 10
SOLENOIDS = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT
_READ_S = 0.05


class _Step:
    """The samples of one step, with arrival times on one clock from the step's start."""

    def __init__(self, device: Device) -> None:
        self.device = device
        self.t0 = time.monotonic()
        self.samples: list[RawSample] = []
        self.last_command_s = math.nan
        #: Device time of the sample the last command answered (UdpDevice echoes the
        #: latest sample it read): the device's watchdog counts from it.
        self.last_echo_t = math.nan
        #: The device's link counters as last reported when the last command was sent:
        #: more stale drops or a restart since mean that command may not have counted.
        self.counters_at_last_command: dict[str, int] = {}
        self._seq = 0
        self.energised_s = 0.0  # commanded-on time of closed intervals
        self._on_since: float | None = None

    def now(self) -> float:
        return time.monotonic() - self.t0

    def read(self, timeout: float = _READ_S) -> Sample | None:
        sample = self.device.read(timeout)
        if sample is not None:
            c = sample.counts
            self.samples.append((self.now(), sample.seq, sample.t, c[0], c[1], c[2], c[3],
                                 int(sample.status)))
        return sample

    def send(self, left: bool, right: bool, stop_heartbeat: bool = False) -> None:
        self._seq += 1
        # Stamped before the send. A pause between the two makes the worker-clock delay
        # longer; a long one can make the command stale on arrival, which `watchdog`
        # detects (a release sooner than the watchdog allows, or the counters).
        now = self.last_command_s = self.now()
        self.counters_at_last_command = self.device.link_counters()
        if self.samples:
            self.last_echo_t = self.samples[-1][2]
        if (left or right) and self._on_since is None:
            self._on_since = now
        elif not (left or right):
            self._close_on(now)
        self.device.send(LockCommand(self._seq, left, right, stop_heartbeat=stop_heartbeat))

    def _close_on(self, now: float) -> None:
        if self._on_since is not None:
            self.energised_s += now - self._on_since
            self._on_since = None

    def device_time(self, worker_s: float) -> float:
        """The device time at step time `worker_s`, at the latest: the device's times
        minus their arrival times, at their largest (the sample that travelled fastest),
        map the worker's clock onto the device's. Any delay on the way only makes a
        sample look older, so this never places the device earlier than it was."""
        lead = max(t - arrived for arrived, _, t, *_ in self.samples)
        return worker_s + lead

    def result(self, request_id: int, ok: bool, message: str, **kw: object) -> BringupResult:
        # A lock still commanded counts until now (the handler releases right after).
        self._close_on(self.now())
        return BringupResult(request_id, ok, message, tuple(self.samples),
                             last_command_s=self.last_command_s,
                             energised_s=self.energised_s, identity=self.device.identity,
                             **kw)  # type: ignore[arg-type]


def handle(cmd: BringupCommand, device: Device) -> BringupResult:
    """Run one bring-up command on `device`; always answered, always released after.
    Only an idle worker runs it (its state machine refuses it otherwise,
    `backend.worker.machine.RULES`)."""
    step = _Step(device)
    try:
        if isinstance(cmd, BringupCapture):
            return capture(cmd, step)
        if isinstance(cmd, BringupPulse):
            return pulse(cmd, step)
        if isinstance(cmd, BringupRelease):
            return hardware_release(cmd, step)
        return watchdog(cmd, step)
    except Exception as exc:  # answered, never a dead worker loop
        return step.result(cmd.request_id, False, f"bring-up step failed: {exc!r}")
    finally:
        device.release()


def capture(cmd: BringupCapture, step: _Step) -> BringupResult:
    """`cmd.seconds` of samples, every one answered with both solenoids off."""
    seconds = min(max(cmd.seconds, SAMPLE_PERIOD_S), CAPTURE_MAX_S)
    needed = max(1, round(seconds / SAMPLE_PERIOD_S))
    # Wall-clock bound: a real-time device delivers `needed` samples in `seconds`; a
    # device that stalls is reported, not waited for.
    give_up = seconds + 2.0
    while len(step.samples) < needed and step.now() < give_up:
        if step.read() is not None:
            step.send(False, False)
    if len(step.samples) < needed:
        return step.result(cmd.request_id, False, f"only {len(step.samples)} of {needed} "
                           f"samples arrived in {give_up:.1f} s: is the device streaming?")
    return step.result(cmd.request_id, True, f"{needed} samples")


def _side_bits(side: str) -> tuple[Status, bool, bool]:
    if side == "left":
        return Status.SOLENOID_LEFT, True, False
    if side == "right":
        return Status.SOLENOID_RIGHT, False, True
    raise ValueError(f"side must be 'left' or 'right', got {side!r}")


def load_reason(sample: Sample, layout: EncoderLayout, max_alpha_deg: float) -> str:
    """Why `sample` shows a loaded or faulty mechanism ("" if it shows none)."""
    st = Status(sample.status)
    if st & (Status.LOCKED_LEFT | Status.LOCKED_RIGHT):
        return f"the device reports a pawl engaged ({st!r}): the mechanism is loaded"
    if st & (Status.HARD_STOP_LEFT | Status.HARD_STOP_RIGHT):
        return f"the device reports a hard stop ({st!r}): the mechanism is loaded"
    if st.is_fault:
        return f"the device reports a fault ({st!r})"
    _, alpha_l, _, alpha_r = layout.joint_angles(sample.counts)
    worst = max(abs(alpha_l), abs(alpha_r))
    if math.degrees(worst) > max_alpha_deg:
        return (f"spring deflection {math.degrees(alpha_l):.2f} deg left, "
                f"{math.degrees(alpha_r):.2f} deg right, beyond {max_alpha_deg:g} deg: the "
                "mechanism is loaded (or the cam offset is not calibrated)")
    return ""


def _precheck(step: _Step, layout: EncoderLayout, max_alpha_deg: float) -> str:
    """Read `PRECHECK_SAMPLES` with the solenoids off; the first load seen, or ""."""
    seen = 0
    while seen < PRECHECK_SAMPLES and step.now() < 2.0:
        sample = step.read()
        if sample is None:
            continue
        step.send(False, False)
        seen += 1
        reason = load_reason(sample, layout, max_alpha_deg)
        if reason:
            return reason
    return "" if seen == PRECHECK_SAMPLES else "the device sent no samples"


#: Why a pulse the device's command watchdog cut is not passed.
WATCHDOG_CUT = ("the device's watchdog released the solenoid during the pulse: the "
                "commands came late (a busy computer or network); try again")


def _lapsed(step: _Step) -> bool:
    """Whether the device's watchdog has released by now for certain: its time (a lower
    bound, `device_time`) is a watchdog's time past the sample the last command
    answered, and no later command can have fed it."""
    return step.device_time(step.now()) - step.last_echo_t > WATCHDOG_S


def pulse(cmd: BringupPulse, step: _Step) -> BringupResult:
    """Energise one solenoid for at most `PULSE_MAX_S`, then release and check both the
    solenoid bit coming on (and only that side's) and going off again."""
    bit, left, right = _side_bits(cmd.side)
    other = SOLENOIDS & ~bit
    layout = EncoderLayout(cmd.offsets, cmd.directions)
    seconds = min(max(cmd.seconds, SAMPLE_PERIOD_S), PULSE_MAX_S)
    refused = _precheck(step, layout, cmd.max_alpha_deg)
    if refused:
        return step.result(cmd.request_id, False, f"pulse refused: {refused}", refused=True)
    began = step.now()
    step.send(left, right)
    first_echo = step.last_echo_t  # the sample the first lock answered
    seen, problem = False, ""
    # On the worker's clock the lock commands cover at most `seconds`: the last one goes
    # out one period before the end, no read waits past it, and the clock is read again
    # after each (possibly late) sample, right before the command. A release that
    # arrives late is bounded by the device's own watchdog (100-110 ms after the sample
    # the last lock answered).
    while (left_s := seconds - SAMPLE_PERIOD_S - (step.now() - began)) >= 0:
        sample = step.read(min(_READ_S, left_s + 1e-3))
        if sample is None:
            continue
        st = Status(sample.status)
        seen = seen or bool(st & bit)
        if st & other:
            problem = f"the {'right' if left else 'left'} solenoid came on instead"
        # The device dropped the solenoid (it says so, or no lock can have reached it in
        # time: the last answered a sample over a watchdog's time ago): the commands came
        # too late. Another would energise it again, a second pulse nobody asked for. A
        # release a previous step left shows until the first lock takes: a watchdog's
        # time after that lock's sample it is this pulse's (seen on or not).
        if (st & Status.WATCHDOG_RELEASED
                and (seen or sample.t >= first_echo + WATCHDOG_S - 1e-6)) or _lapsed(step):
            problem = problem or WATCHDOG_CUT
        problem = problem or load_reason(sample, layout, cmd.max_alpha_deg)
        if problem or step.now() - began + SAMPLE_PERIOD_S > seconds:
            break
        step.send(left, right)
    step.send(False, False)
    released = False
    for _ in range(RELEASE_SAMPLES * 3):
        sample = step.read()
        if sample is None:
            continue
        step.send(False, False)
        st = Status(sample.status)
        if seen and st & Status.WATCHDOG_RELEASED:
            # Off, but by the watchdog before the release arrived: the locks came late.
            problem = problem or WATCHDOG_CUT
        if not st & SOLENOIDS:
            released = True
            break
    if problem:
        return step.result(cmd.request_id, False, f"pulse stopped: {problem}",
                           solenoid_seen=seen, released_seen=released)
    if not seen:
        msg = f"the device never reported SOLENOID_{cmd.side.upper()} during the pulse"
    elif not released:
        msg = "the device still reports a solenoid energised after the pulse"
    else:
        msg = f"SOLENOID_{cmd.side.upper()} came on and went off"
    return step.result(cmd.request_id, seen and released, msg, solenoid_seen=seen,
                       released_seen=released)


def _untaken(step: _Step, device_s: float) -> str:
    """Why the last command was not the one the device's watchdog counted from, or "".
    A release sooner than the watchdog allows proves it: the device dropped the command
    (stale on arrival: a worker on a busy machine answered a sample over 100 ms old) or
    never got it, and the drop itself is reported only in frames after the release. A
    restart of the device, or a stale drop reported by now, says so too."""
    now = step.device.link_counters()
    before = step.counters_at_last_command
    if now.get("device_restarts", 0) != before.get("device_restarts", 0):
        return "the device restarted during the silence"
    if device_s < WATCHDOG_S - 1e-6:
        return (f"the device released {1000 * device_s:.1f} ms after the sample the last "
                f"command answered, sooner than its {1000 * WATCHDOG_S:.0f} ms watchdog "
                "allows: it did not take that command")
    if now.get("device_stale", 0) > before.get("device_stale", 0):
        return "the device dropped a command as stale after the last one was sent"
    return ""


def watchdog(cmd: BringupWatchdog, step: _Step) -> BringupResult:
    """Energise one solenoid until the device reports it, then send nothing and time the
    first sample with WATCHDOG_RELEASED and the solenoids off."""
    if step.device.kind != "udp":
        return step.result(cmd.request_id, False, "the command watchdog lives in the device: "
                           "this test needs a device on the UDP link (hardware or the "
                           "device simulator)", refused=True)
    bit, left, right = _side_bits(cmd.side)
    layout = EncoderLayout(cmd.offsets, cmd.directions)
    refused = _precheck(step, layout, cmd.max_alpha_deg)
    if refused:
        return step.result(cmd.request_id, False, f"watchdog test refused: {refused}",
                           refused=True)
    began = step.now()
    step.send(left, right)
    seen = False
    while not seen and step.now() - began + SAMPLE_PERIOD_S <= PULSE_MAX_S:
        sample = step.read()
        if sample is None:
            continue
        seen = bool(Status(sample.status) & bit)
        if not seen:
            step.send(left, right)
    if not seen:
        return step.result(cmd.request_id, False, f"the device never reported "
                           f"SOLENOID_{cmd.side.upper()}: nothing to release")
    # Silence: no command from here on (HELLO packets do not feed the watchdog).
    last = step.last_command_s
    while step.now() - last < WATCHDOG_WAIT_S:
        sample = step.read()
        if sample is None:
            continue
        st = Status(sample.status)
        if st & Status.WATCHDOG_RELEASED and not st & SOLENOIDS:
            release_s = step.samples[-1][0] - last
            # The watchdog counts from the sample the last command answered (protocol
            # version 3, safety rule 1), both times on the device's own clock.
            echoed = step.last_echo_t
            device_s = sample.t - (echoed if not math.isnan(echoed)
                                   else step.device_time(last))
            untaken = _untaken(step, device_s)
            if untaken:
                return step.result(cmd.request_id, False, f"not measured: {untaken}, so its "
                                   "watchdog ran from another command than the one timed; "
                                   "run the step again", solenoid_seen=True,
                                   released_seen=True)
            return step.result(cmd.request_id, True, f"released {1000 * device_s:.1f} ms "
                               f"after the sample the last command answered (device "
                               f"clock; {1000 * release_s:.1f} ms after the last command "
                               f"to the worker)",
                               solenoid_seen=True, released_seen=True, release_s=release_s,
                               release_device_s=device_s)
    return step.result(cmd.request_id, False, f"the device did not release within "
                       f"{1000 * WATCHDOG_WAIT_S:.0f} ms of the last command",
                       solenoid_seen=True)


def _needs_link(step: _Step, request_id: int, what: str) -> BringupResult | None:
    if step.device.kind == "udp":
        return None
    return step.result(request_id, False, f"{what}: this test needs a device on the UDP "
                       "link (hardware or a device simulator)", refused=True)


def _energise(step: _Step, side: str, stop_heartbeat: bool = False) -> Sample | None:
    """Command `side` on until the device reports its solenoid (at most `PULSE_MAX_S`);
    the sample that showed it, or None."""
    bit, left, right = _side_bits(side)
    began = step.now()
    step.send(left, right, stop_heartbeat)
    while step.now() - began + SAMPLE_PERIOD_S <= PULSE_MAX_S:
        sample = step.read()
        if sample is None:
            continue
        if Status(sample.status) & bit:
            return sample
        step.send(left, right, stop_heartbeat)
    return None


def hardware_release(cmd: BringupRelease, step: _Step) -> BringupResult:
    """Energise one solenoid with the heartbeat running, then keep commanding it with
    STOP_HEARTBEAT: the firmware stops toggling its heartbeat output and the external
    monostable must cut the drivers by itself. Times, on the device's clock, the first
    sample with HEARTBEAT_STOPPED to the first with DRIVERS_OFF (the server judges it);
    then releases, resumes the heartbeat and checks that the drivers come back."""
    refused = _needs_link(step, cmd.request_id, "the hardware release lives on the board")
    if refused is not None:
        return refused
    bit, left, right = _side_bits(cmd.side)
    layout = EncoderLayout(cmd.offsets, cmd.directions)
    reason = _precheck(step, layout, cmd.max_alpha_deg)
    if reason:
        return step.result(cmd.request_id, False, f"hardware release test refused: {reason}",
                           refused=True)
    on = _energise(step, cmd.side)
    if on is None:
        return step.result(cmd.request_id, False, f"the device never reported "
                           f"SOLENOID_{cmd.side.upper()}: nothing to release")
    if Status(on.status) & Status.DRIVERS_OFF:
        return step.result(cmd.request_id, False, "the device reports DRIVERS_OFF while its "
                           "heartbeat runs: the drivers' enable readback is miswired, or the "
                           "monitor never enables them", solenoid_seen=True)
    # Keep the lock asked for, heartbeat stopped: only the hardware can release now.
    stopped_t = drivers_off_t = math.nan
    began = step.now()
    step.send(left, right, stop_heartbeat=True)
    while True:
        sample = step.read()
        waited = step.now() - began
        if sample is not None:
            st = Status(sample.status)
            if math.isnan(stopped_t) and st & Status.HEARTBEAT_STOPPED:
                stopped_t = sample.t
            if not math.isnan(stopped_t) and st & Status.DRIVERS_OFF:
                drivers_off_t = sample.t
                break
            if not math.isnan(stopped_t) and sample.t - stopped_t > RELEASE_WAIT_S:
                break
        if math.isnan(stopped_t) and waited > RELEASE_WAIT_S:
            break
        if waited > 2 * RELEASE_WAIT_S + 0.5:  # a device that stalls is not waited for
            break
        if sample is not None:
            step.send(left, right, stop_heartbeat=True)
    # Release, heartbeat back on: the drivers must be enabled again.
    step.send(False, False)
    back = False
    resumed = step.now()
    while step.now() - resumed < DRIVERS_BACK_WAIT_S:
        sample = step.read()
        if sample is None:
            continue
        step.send(False, False)
        st = Status(sample.status)
        if not st & (Status.DRIVERS_OFF | Status.HEARTBEAT_STOPPED | bit):
            back = True
            break
    seen = dict(solenoid_seen=True, heartbeat_stopped_t=stopped_t,
                drivers_off_t=drivers_off_t, drivers_back=back)
    if math.isnan(stopped_t):
        return step.result(cmd.request_id, False, "the device never reported "
                           "HEARTBEAT_STOPPED: its firmware does not honour STOP_HEARTBEAT "
                           "(protocol 3)", **seen)
    if math.isnan(drivers_off_t):
        return step.result(cmd.request_id, False, "no DRIVERS_OFF within "
                           f"{1000 * RELEASE_WAIT_S:.0f} ms of HEARTBEAT_STOPPED", **seen)
    delay_ms = 1000 * (drivers_off_t - stopped_t)
    return step.result(cmd.request_id, True, f"drivers off {delay_ms:.1f} ms after the "
                       "heartbeat stopped (device clock)",
                       released_seen=back, **seen)
