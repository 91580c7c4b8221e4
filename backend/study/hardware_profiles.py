"""Hardware bring-up: run its steps through the worker, judge them, and keep the result
as a hardware profile (docs/hardware-bringup.md).

Steps write into one draft profile, bound to the device the steps ran on (its key id
and the unique id and firmware it proved on the link) and closed as `expired` when
another device comes on the link or `DRAFT_LIFETIME` passes; finishing it makes it
`complete` (every step passed: the profile in effect from then on, recorded on every
new session and trial and applied only to that device) or `failed` (kept for the
record). Refusals that protect a person (something running, a controller other than
`none`, no confirmation that nobody wears the exoskeleton, a solenoid still cooling
down, a device that shows a load) raise before anything is energised and store nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.hardware import HardwareProfile
from backend.db.models import User
from backend.live.device_binding import BoundDevice, firmware_notice, mismatch
from backend.live.runtime import Runtime
from backend.live.solenoid_duty import MAX_ON_S
from backend.schemas.hardware import (
    STEP_NAMES,
    CaptureIn,
    DirectionIn,
    FinishIn,
    HardwareStateOut,
    ProfileOut,
    PulseIn,
    ReleaseIn,
    StepOut,
    StepResultOut,
    WatchdogIn,
)
from backend.study import activity
from backend.worker.messages import (
    BringupCapture,
    BringupCommand,
    BringupPulse,
    BringupRelease,
    BringupResult,
    BringupWatchdog,
)
from controller.controllers import registry
from controller.lowlevel import bringup as calc
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout

#: The device must release within this long of the last command: its 100 ms watchdog
#: checked once per 10 ms sample period (docs/device-protocol.md, safety rule 1).
WATCHDOG_LIMIT_S = 0.110
#: The simulated wearer's posture for each kind of step (controller/sim/scripts.py).
STANDING_SCRIPT = "standing"
#: A draft is closed as `expired` this long after it was opened: a bring-up is one
#: sitting; a draft left overnight must not collect steps measured on another day.
DRAFT_LIFETIME = timedelta(hours=2)
#: The heartbeat monitor holds the drivers' enable 30 ms after the last edge in the
#: simulators (HEARTBEAT_HOLD) and 27.3-39.2 ms worst case on the lab's circuit
#: (docs/hardware-bringup-lab.md, "Hardware release (heartbeat)"). The last edge comes one
#: period before the first sample that reports the heartbeat stopped and the enable is
#: read once per 10 ms sample, so that circuit reads as 20-30 ms, 40 ms with one period of
#: jitter: DRIVERS_OFF must follow within 40 ms, the lab checklist's bound.
HEARTBEAT_HOLD_S = 0.030
RELEASE_LIMIT_S = 0.040
#: Sooner than this, the hold is far shorter than designed (one late sample in a study
#: would cut the drivers): the lab's checklist's lower bound.
RELEASE_MIN_S = 0.010
RELEASE_HELP = ("no hardware release observed: is the heartbeat monitor fitted and its "
                "readback wired? see docs/hardware-bringup-lab.md#hardware-release-heartbeat")
FLEX_SCRIPT = {"left": "hip-flex-left", "right": "hip-flex-right"}


# ------------------------------------------------------------------ what the device is


def device_label(runtime: Runtime) -> str:
    """`sim` (in-process simulator), `udp-sim` (the device process this server spawns)
    or `udp` (an exoskeleton on the network)."""
    s = runtime.settings
    if s.device_kind == "sim":
        return "sim"
    return "udp-sim" if s.device_spawn_simulator else "udp"


def current_device(runtime: Runtime) -> BoundDevice:
    """The device on the link as profiles record it; 409 while it has not proved its
    identity (a step's result could not be bound to a device)."""
    device = runtime.bound_device()
    if device is None:
        raise ConflictError("device", "the device on the link has not proved its identity "
                            "yet (no CHALLENGE answered): is it on and streaming? Bring-up "
                            "needs to know which device it measures")
    return device


def firmware_version(device: BoundDevice, given: str | None) -> str:
    """The device's firmware as it reported it; what the experimenter entered only for
    a device that reports none."""
    return device.firmware or (given or "").strip() or "not reported"


# ------------------------------------------------------------------ profiles


def active(db: Session) -> HardwareProfile | None:
    """The profile in effect: the latest completed one."""
    return db.scalars(select(HardwareProfile).where(HardwareProfile.status == "complete")
                      .order_by(HardwareProfile.id.desc()).limit(1)).first()


def active_id(db: Session) -> int | None:
    """Id of the profile in effect (recorded on sessions and trials), None if none."""
    p = active(db)
    return None if p is None else p.id


def draft(db: Session) -> HardwareProfile | None:
    """The bring-up in progress, if any."""
    return db.scalars(select(HardwareProfile).where(HardwareProfile.status == "draft")
                      .order_by(HardwareProfile.id.desc()).limit(1)).first()


def layout_of(profile: HardwareProfile) -> EncoderLayout:
    """The encoder layout a profile stores."""
    return EncoderLayout(tuple(profile.encoder_offsets),  # type: ignore[arg-type]
                         tuple(profile.encoder_directions))  # type: ignore[arg-type]


def _cam_output(offsets: list[int]) -> list[int]:
    return [int(calc.wrap(offsets[1] - offsets[0])), int(calc.wrap(offsets[3] - offsets[2]))]


def bound_to(profile: HardwareProfile) -> BoundDevice:
    """The device a profile or draft was made on."""
    return BoundDevice(profile.device, profile.key_id, profile.unique_id,
                       profile.firmware_version)


def _aware(t: datetime) -> datetime:
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def _stale(d: HardwareProfile, device: BoundDevice, now: datetime) -> str:
    """Why draft `d` may take no more steps on `device` ("" if it may)."""
    if d.expires_at is not None and _aware(d.expires_at) <= now:
        return (f"it expired at {_aware(d.expires_at):%Y-%m-%d %H:%M} UTC "
                f"({DRAFT_LIFETIME.total_seconds() / 3600:g} h after it was opened)")
    why = mismatch(bound_to(d), device)
    return f"it belongs to another device ({why})" if why else ""


def close_stale_draft(db: Session, user: User, device: BoundDevice) -> str:
    """Close the draft as `expired` if it is past its lifetime or was opened on another
    device (it is kept for the record); a note for the step's message ("" if none)."""
    d = draft(db)
    if d is None:
        return ""
    why = _stale(d, device, datetime.now(UTC))
    if not why:
        return ""
    d.status = "expired"
    d.completed_at = datetime.now(UTC)
    audit.record(db, user, "expire", "hardware_profile", d.id, {"reason": why})
    db.commit()
    return f"; draft {d.id} was closed unfinished: {why}"


def _draft_for(db: Session, user: User, runtime: Runtime,
               device: BoundDevice) -> HardwareProfile:
    """The draft of `device`, created from the profile in effect (else the default
    layout); `close_stale_draft` has already closed one of another device."""
    d = draft(db)
    if d is not None:
        return d
    base = active(db)
    lay = layout_of(base) if base is not None else DEFAULT_LAYOUT
    now = datetime.now(UTC)
    d = HardwareProfile(status="draft", device=device.kind,
                        firmware_version=firmware_version(device, None),
                        key_id=device.key_id, unique_id=device.unique_id,
                        precompression_pct=runtime.settings.precompression_pct,
                        encoder_offsets=list(lay.offsets),
                        encoder_directions=list(lay.directions),
                        cam_output_offsets=_cam_output(list(lay.offsets)), steps={},
                        created_by=user.id, created_at=now, expires_at=now + DRAFT_LIFETIME)
    db.add(d)
    db.flush()
    return d


def state(db: Session, runtime: Runtime) -> HardwareStateOut:
    """The draft, the profile in effect, the layout the worker applies and why."""
    lay = runtime.encoder_layout or DEFAULT_LAYOUT
    device = runtime.bound_device()
    d, a = draft(db), active(db)
    note = notice = ""
    if runtime.hardware_is_simulated:
        note = ("simulated device: the worker keeps the simulator's own encoder mounting; "
                "profiles measured on it are stored, not applied")
    elif a is None:
        note = "no completed hardware profile yet: the default encoder layout applies"
    else:
        note = runtime.profile_verdict()
        if note:
            note += "; the default encoder layout applies meanwhile"
        elif device is not None:
            notice = firmware_notice(bound_to(a), device)
    return HardwareStateOut(
        device=device_label(runtime), simulated=runtime.hardware_is_simulated,
        steps=list(STEP_NAMES),
        draft=None if d is None else ProfileOut.model_validate(d),
        active=None if a is None else ProfileOut.model_validate(a),
        applied_offsets=list(lay.offsets), applied_directions=list(lay.directions),
        applied_note=note, identity="" if device is None else device.describe(),
        firmware_notice=notice,
        cooldown_s={side: round(runtime.solenoid_duty.wait_s(side), 2)
                    for side in ("left", "right")})


def list_profiles(db: Session) -> list[HardwareProfile]:
    """Every profile, newest first."""
    return list(db.scalars(select(HardwareProfile).order_by(HardwareProfile.id.desc())))


def get(db: Session, profile_id: int) -> HardwareProfile:
    """One profile; NotFoundError if there is none with that id."""
    p = db.get(HardwareProfile, profile_id)
    if p is None:
        raise NotFoundError("hardware profile", profile_id)
    return p


# ------------------------------------------------------------------ running a step


def ensure_free(db: Session, runtime: Runtime) -> None:
    """The one check every step and every change of a profile makes: 409 while a
    trial, a recording or a controller other than `none` runs (or no worker does)."""
    busy = activity.running(db)
    if busy is not None:
        raise ConflictError("hardware", f"{busy} is running: bring-up needs the device "
                            "to itself; stop it first")
    ctl = runtime.supervisor.config.controller
    if ctl != registry.idle():
        raise ConflictError("hardware", f"controller {ctl!r} is active: switch to "
                            f"{registry.idle()!r} before the bring-up")
    if not runtime.supervisor.state.alive:
        raise ConflictError("worker", "the worker is not running: restart it first")


async def _posture(runtime: Runtime, script: str) -> str:
    """On a simulator, put the simulated wearer in the posture the step asks of a
    person; returns a note for the step's message ("" on hardware)."""
    if not runtime.hardware_is_simulated:
        return ""
    if runtime.settings.device_script != script:
        try:
            await runtime.set_simulation(runtime.settings.device_seed, script)
        except (RuntimeError, ValueError) as exc:
            raise ConflictError("simulation", f"could not put the simulated wearer in "
                                f"script {script!r}: {exc}") from exc
    return f" (simulated wearer: {script})"


def _begin(db: Session, user: User, runtime: Runtime) -> tuple[BoundDevice, str]:
    """Before a step: the device is free, has proved who it is, and a draft of another
    device or past its lifetime is closed (the device, and a note saying so)."""
    ensure_free(db, runtime)
    device = current_device(runtime)
    return device, close_stale_draft(db, user, device)


async def _worker(runtime: Runtime, cmd: BringupCommand, device: BoundDevice,
                  side: str | None = None) -> BringupResult:
    """Run `cmd` in the worker; a step that energises `side` is charged to its duty
    cycle (the worst case when the worker did not answer)."""
    try:
        result = await runtime.bringup(cmd)
    except RuntimeError as exc:
        if side is not None:
            runtime.solenoid_duty.record(side, MAX_ON_S)
        raise ConflictError("worker", str(exc)) from exc
    if side is not None:
        runtime.solenoid_duty.record(side, result.energised_s)
    if result.refused:
        raise ConflictError("hardware", result.message)
    if device.kind != "sim":
        seen = None if result.identity is None else BoundDevice.of(device.kind,
                                                                   result.identity)
        why = "it did not prove its identity" if seen is None else mismatch(device, seen)
        if why:
            raise ConflictError("device", f"the device changed during the step ({why}): "
                                "nothing was stored; run the step again")
    return result


def _duty(runtime: Runtime, side: str) -> None:
    """409 while `side`'s solenoid is cooling down (its duty-cycle budget)."""
    why = runtime.solenoid_duty.refusal(side)
    if why:
        raise ConflictError("solenoid", why)


def _store(db: Session, user: User, profile: HardwareProfile, step: str, passed: bool,
           message: str, values: dict[str, Any]) -> StepResultOut:
    out = StepOut(passed=passed, message=message, at=datetime.now(UTC), values=values)
    profile.steps = {**profile.steps, step: out.model_dump(mode="json")}
    audit.record(db, user, "bringup", "hardware_profile", profile.id,
                 {"step": step, "passed": passed, "message": message})
    db.commit()
    db.refresh(profile)
    return StepResultOut(step=step, result=out, profile=ProfileOut.model_validate(profile))


def _confirm(nobody_wearing: bool) -> None:
    if not nobody_wearing:
        raise InvalidError([(["body", "nobody_wearing"], "confirm that nobody wears the "
                            "exoskeleton (true): a solenoid energised under load could lock "
                            "a side on a person")])


#: What a capture step makes of its samples: it updates the draft profile and returns
#: the step's message and details, or raises `calc.BringupError` to fail the step.
Judge = Callable[[HardwareProfile, Any], tuple[str, dict[str, Any]]]


async def _capture_step(db: Session, user: User, runtime: Runtime, step: str, script: str,
                        seconds: float, judge: Judge) -> StepResultOut:
    """The shape every capture step shares: put the wearer in `script`'s posture (a
    simulator only), capture `seconds` of samples, judge them, store the outcome."""
    async with runtime.activity:
        device, closed = _begin(db, user, runtime)
        note = await _posture(runtime, script)
        result = await _worker(runtime, BringupCapture(seconds), device)
        profile = _draft_for(db, user, runtime, device)
        note += closed
        if not result.ok:
            return _store(db, user, profile, step, False, result.message + note, {})
        try:
            message, details = judge(profile, result.samples)
        except calc.BringupError as exc:
            return _store(db, user, profile, step, False, str(exc) + note, {})
        return _store(db, user, profile, step, True, message + note, details)


async def zero(db: Session, user: User, runtime: Runtime, body: CaptureIn) -> StepResultOut:
    """Step a: each encoder's count at the standing posture becomes its zero."""

    def judge(profile: HardwareProfile, samples: Any) -> tuple[str, dict[str, Any]]:
        z = calc.zero(samples)
        profile.encoder_offsets = list(z.offsets)
        profile.cam_output_offsets = _cam_output(list(z.offsets))
        return (f"zeroed over {len(samples)} still samples",
                {"offsets": list(z.offsets), "std_deg": [round(s, 4) for s in z.std_deg],
                 "samples": len(samples)})

    return await _capture_step(db, user, runtime, "zero", STANDING_SCRIPT, body.seconds, judge)


async def direction(db: Session, user: User, runtime: Runtime,
                    body: DirectionIn) -> StepResultOut:
    """Step b: the experimenter flexes one hip; its encoders' signs are stored so that
    its output angle rises with flexion."""

    def judge(profile: HardwareProfile, samples: Any) -> tuple[str, dict[str, Any]]:
        zeroed = profile.steps.get("zero", {}).get("passed", False)
        d = calc.direction(samples, body.side, reference=tuple(  # type: ignore[arg-type]
            profile.encoder_offsets) if zeroed else None)
        out, cam = calc.INDEX[body.side]
        dirs = list(profile.encoder_directions)
        dirs[out], dirs[cam] = d.output_direction, d.cam_direction
        profile.encoder_directions = dirs
        return (f"{body.side} hip flexed {d.moved_deg:.1f} deg: output direction "
                f"{d.output_direction:+d}, cam {d.cam_direction:+d}",
                {"output_direction": d.output_direction, "cam_direction": d.cam_direction,
                 "moved_deg": round(d.moved_deg, 2),
                 "other_moved_deg": round(d.other_moved_deg, 2)})

    return await _capture_step(db, user, runtime, f"direction_{body.side}",
                               FLEX_SCRIPT[body.side], body.seconds, judge)


async def offset(db: Session, user: User, runtime: Runtime, body: CaptureIn) -> StepResultOut:
    """Step c: the cam encoders' zeros that make alpha = 0 while the sides are free."""

    def judge(profile: HardwareProfile, samples: Any) -> tuple[str, dict[str, Any]]:
        c = calc.cam_offset(samples, layout_of(profile))
        offs = list(profile.encoder_offsets)
        offs[1], offs[3] = c.cam_offsets
        profile.encoder_offsets = offs
        profile.cam_output_offsets = list(c.cam_output_offsets)
        return (f"alpha within {max(c.alpha_max_deg):.2f} deg while unlocked",
                {"cam_output_offsets": list(c.cam_output_offsets),
                 "alpha_max_deg": [round(v, 3) for v in c.alpha_max_deg],
                 "alpha_std_deg": [round(v, 3) for v in c.alpha_std_deg]})

    return await _capture_step(db, user, runtime, "offset", STANDING_SCRIPT, body.seconds,
                               judge)


def _judging_layout(db: Session) -> EncoderLayout:
    d = draft(db) or active(db)
    return DEFAULT_LAYOUT if d is None else layout_of(d)


async def pulse(db: Session, user: User, runtime: Runtime, body: PulseIn) -> StepResultOut:
    """Step d: one bounded solenoid pulse on an unloaded device nobody wears."""
    _confirm(body.nobody_wearing)
    step = f"pulse_{body.side}"
    async with runtime.activity:
        device, closed = _begin(db, user, runtime)
        _duty(runtime, body.side)
        note = await _posture(runtime, STANDING_SCRIPT)
        lay = _judging_layout(db)
        result = await _worker(runtime, BringupPulse(
                body.side, body.duration_ms / 1000.0, lay.offsets, lay.directions,
                calc.ALPHA_TOLERANCE_DEG), device, body.side)
        profile = _draft_for(db, user, runtime, device)
        return _store(db, user, profile, step, result.ok, result.message + note + closed,
                      {"duration_ms": body.duration_ms, "solenoid_seen": result.solenoid_seen,
                       "released_seen": result.released_seen,
                       "energised_ms": round(1000 * result.energised_s, 1),
                       "samples": len(result.samples)})


async def watchdog(db: Session, user: User, runtime: Runtime,
                   body: WatchdogIn) -> StepResultOut:
    """Step e: energise one side, go silent, time the device's release."""
    _confirm(body.nobody_wearing)
    async with runtime.activity:
        device, closed = _begin(db, user, runtime)
        _duty(runtime, body.side)
        note = await _posture(runtime, STANDING_SCRIPT)
        lay = _judging_layout(db)
        result = await _worker(runtime, BringupWatchdog(
                body.side, lay.offsets, lay.directions, calc.ALPHA_TOLERANCE_DEG),
            device, body.side)
        note += closed
        profile = _draft_for(db, user, runtime, device)
        release_ms = None if math.isnan(result.release_s) else round(1000 * result.release_s, 2)
        device_ms = (None if math.isnan(result.release_device_s)
                     else round(1000 * result.release_device_s, 2))
        # Judged on the device's clock (see `BringupResult.release_device_s`): a bound on
        # the device's own delay that the worker's scheduling cannot push past the limit.
        passed = result.ok and device_ms is not None and device_ms <= 1000 * WATCHDOG_LIMIT_S
        message = result.message
        if result.ok and not passed:
            message += f": later than {1000 * WATCHDOG_LIMIT_S:.0f} ms"
        return _store(db, user, profile, "watchdog", passed, message + note,
                      {"side": body.side, "release_ms": release_ms,
                       "device_release_ms": device_ms,
                       "limit_ms": 1000 * WATCHDOG_LIMIT_S,
                       "solenoid_seen": result.solenoid_seen,
                       "released_seen": result.released_seen})


async def hardware_release(db: Session, user: User, runtime: Runtime,
                           body: ReleaseIn) -> StepResultOut:
    """Step f: energise one side, stop the firmware's heartbeat output (STOP_HEARTBEAT on
    the commands, the lock still asked for) and time on the device's clock how long
    the external heartbeat monitor takes to cut the drivers."""
    _confirm(body.nobody_wearing)
    async with runtime.activity:
        device, closed = _begin(db, user, runtime)
        _duty(runtime, body.side)
        note = await _posture(runtime, STANDING_SCRIPT)
        lay = _judging_layout(db)
        result = await _worker(runtime, BringupRelease(
                body.side, lay.offsets, lay.directions, calc.ALPHA_TOLERANCE_DEG),
            device, body.side)
        profile = _draft_for(db, user, runtime, device)
        passed, message, delay_ms = judge_release(result)
        return _store(db, user, profile, "hardware_release", passed,
                      message + note + closed,
                      {"side": body.side, "release_ms": delay_ms,
                       "limit_ms": round(1000 * RELEASE_LIMIT_S, 1),
                       "heartbeat_stopped_seen": not math.isnan(result.heartbeat_stopped_t),
                       "drivers_back": result.drivers_back,
                       "energised_ms": round(1000 * result.energised_s, 1)})


def judge_release(result: BringupResult) -> tuple[bool, str, float | None]:
    """The hardware release step's verdict from the worker's timing: (passed, message,
    the delay in ms or None). Passes when DRIVERS_OFF follows HEARTBEAT_STOPPED within
    `RELEASE_LIMIT_S` on the device's clock and the drivers come back after."""
    stopped, off = result.heartbeat_stopped_t, result.drivers_off_t
    if math.isnan(stopped):
        return False, result.message, None
    if math.isnan(off):
        return False, RELEASE_HELP, None
    delay_ms = round(1000 * (off - stopped), 2)
    limit_ms = 1000 * RELEASE_LIMIT_S
    if delay_ms < 1000 * RELEASE_MIN_S:
        return False, (f"drivers off only {delay_ms:.1f} ms after the heartbeat stopped: "
                       f"the hold is far shorter than 30 ms (at least "
                       f"{1000 * RELEASE_MIN_S:.0f} ms expected); check the monostable's "
                       "timing parts"), delay_ms
    if delay_ms > limit_ms:
        return False, (f"drivers off {delay_ms:.1f} ms after the heartbeat stopped: later "
                       f"than {limit_ms:.0f} ms (the circuit's longest hold, read once per "
                       "sample); check the "
                       "monostable's timing parts"), delay_ms
    if not result.drivers_back:
        return False, (f"drivers off {delay_ms:.1f} ms after the heartbeat stopped, but "
                       "they did not come back on when it resumed"), delay_ms
    return True, (f"drivers off {delay_ms:.1f} ms after the heartbeat stopped (at most "
                  f"{limit_ms:.0f} ms), back on when it resumed"), delay_ms


async def link(db: Session, user: User, runtime: Runtime) -> StepResultOut:
    """Step g: the link's statistics as the worker reports them; passes while the
    device streams and nothing was dropped for authentication or as malformed."""
    async with runtime.activity:
        device, closed = _begin(db, user, runtime)
        h = runtime.health()
        profile = _draft_for(db, user, runtime, device)
        drops = dict(h.device.link_drops)
        bad = {k: v for k, v in drops.items()
               if k in ("auth", "malformed", "replay", "device_auth") and v}
        passed = h.device.alive and not bad
        if not h.device.alive:
            message = "the device is not streaming"
        elif bad:
            message = "dropped packets: " + ", ".join(f"{k} {v}" for k, v in bad.items())
        else:
            message = "streaming; no packet dropped for authentication or as malformed"
        message += closed
        values: dict[str, Any] = {
            "link_drops": drops, "gaps": h.worker.gaps, "timeouts": h.worker.timeouts,
            "ticks": h.worker.ticks,
            "jitter_p99_ms": _finite(h.worker.jitter_p99_ms),
            "compute_p99_us": _finite(h.worker.compute_p99_us),
            "last_sample_age_s": _finite(h.device.last_sample_age_s),
        }
        return _store(db, user, profile, "link", passed, message, values)


def _finite(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else round(float(v), 4)


async def finish(db: Session, user: User, runtime: Runtime, body: FinishIn) -> HardwareProfile:
    """Close the draft: `complete` if every step passed (then it is in effect and, on
    hardware, the worker decodes with its layout from the next run on), else `failed`."""
    async with runtime.activity:
        ensure_free(db, runtime)
        device = current_device(runtime)
        closed = close_stale_draft(db, user, device)
        profile = draft(db)
        if profile is None:
            raise ConflictError("hardware", "no bring-up in progress" + closed
                                + ": run the steps on this device first")
        missing = [s for s in STEP_NAMES if not profile.steps.get(s, {}).get("passed")]
        profile.firmware_version = firmware_version(device, body.firmware_version)
        profile.status = "failed" if missing else "complete"
        profile.completed_at = datetime.now(UTC)
        audit.record(db, user, "finish", "hardware_profile", profile.id,
                     {"status": profile.status, "not_passed": missing})
        db.commit()
        db.refresh(profile)
        if profile.status == "complete":
            runtime.load_hardware_layout()
            if (activity.running(db) is None
                    and runtime.supervisor.config.controller == registry.idle()):
                await runtime.idle()  # `none` again, decoding with the new layout
        return profile
