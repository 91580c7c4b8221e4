"""Hardware bring-up: run its steps through the worker, judge them, and keep the result
as a hardware profile (docs/hardware-bringup.md).

Steps write into one draft profile; finishing it makes it `complete` (every step
passed: the profile in effect from then on, recorded on every new session and trial)
or `failed` (kept for the record). Refusals that protect a person (something running,
a controller other than `none`, no confirmation that nobody wears the exoskeleton, a
device that shows a load) raise before anything is energised and store nothing.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.core.resources import version
from backend.db.hardware import HardwareProfile
from backend.db.models import User
from backend.live.runtime import Runtime
from backend.schemas.hardware import (
    STEP_NAMES,
    CaptureIn,
    DirectionIn,
    FinishIn,
    HardwareStateOut,
    ProfileOut,
    PulseIn,
    StepOut,
    StepResultOut,
    WatchdogIn,
)
from backend.study import activity, audit
from backend.worker.messages import (
    BringupCapture,
    BringupCommand,
    BringupPulse,
    BringupResult,
    BringupWatchdog,
)
from controller.controllers import registry
from controller.device.auth import load_key
from controller.lowlevel import bringup as calc
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout

#: The device must release within this long of the last command: its 100 ms watchdog
#: checked once per 10 ms sample period (docs/device-protocol.md, safety rule 1).
WATCHDOG_LIMIT_S = 0.110
#: The simulated wearer's posture for each kind of step (controller/sim/scripts.py).
STANDING_SCRIPT = "standing"
FLEX_SCRIPT = {"left": "hip-flex-left", "right": "hip-flex-right"}


# ------------------------------------------------------------------ what the device is


def device_label(runtime: Runtime) -> str:
    """`sim` (in-process simulator), `udp-sim` (the device process this server spawns)
    or `udp` (an exoskeleton on the network)."""
    s = runtime.settings
    if s.device_kind == "sim":
        return "sim"
    return "udp-sim" if s.device_spawn_simulator else "udp"


def key_id(runtime: Runtime) -> str:
    """First 8 hex digits of SHA-256 of the link key: tells keys apart, reveals nothing
    usable; "" for the in-process simulator (no link)."""
    if runtime.settings.device_kind != "udp":
        return ""
    try:
        key = load_key(runtime.settings.device_key_file)
    except (OSError, ValueError):
        return "unreadable"
    return hashlib.sha256(key).hexdigest()[:8]


def firmware_version(runtime: Runtime, given: str | None) -> str:
    """The device's version. The wire protocol (version 2) has no field for it, so the
    simulators are named from this installation and real firmware's version is what
    the experimenter enters (its boot banner or label)."""
    label = device_label(runtime)
    if label == "sim":
        return f"in-process simulator, ExoStudy {version()}"
    if label == "udp-sim":
        impl = getattr(runtime.settings, "device_implementation", "python")
        return f"device simulator ({impl}), ExoStudy {version()}, protocol 2"
    return (given or "").strip() or "not reported (protocol 2)"


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


def _draft_for(db: Session, user: User, runtime: Runtime) -> HardwareProfile:
    """The draft, created from the profile in effect (else the default layout)."""
    d = draft(db)
    if d is not None:
        return d
    base = active(db)
    lay = layout_of(base) if base is not None else DEFAULT_LAYOUT
    d = HardwareProfile(status="draft", device=device_label(runtime),
                        firmware_version=firmware_version(runtime, None),
                        key_id=key_id(runtime),
                        precompression_pct=runtime.settings.precompression_pct,
                        encoder_offsets=list(lay.offsets),
                        encoder_directions=list(lay.directions),
                        cam_output_offsets=_cam_output(list(lay.offsets)), steps={},
                        created_by=user.id)
    db.add(d)
    db.flush()
    return d


def state(db: Session, runtime: Runtime) -> HardwareStateOut:
    """The draft, the profile in effect and the layout the worker applies."""
    lay = runtime.encoder_layout or DEFAULT_LAYOUT
    note = ""
    if runtime.hardware_is_simulated:
        note = ("simulated device: the worker keeps the simulator's own encoder mounting; "
                "profiles measured on it are stored, not applied")
    elif runtime.encoder_layout is None:
        note = "no completed hardware profile yet: the default encoder layout applies"
    d, a = draft(db), active(db)
    return HardwareStateOut(
        device=device_label(runtime), simulated=runtime.hardware_is_simulated,
        steps=list(STEP_NAMES),
        draft=None if d is None else ProfileOut.model_validate(d),
        active=None if a is None else ProfileOut.model_validate(a),
        applied_offsets=list(lay.offsets), applied_directions=list(lay.directions),
        applied_note=note)


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


def _ensure_free(db: Session, runtime: Runtime) -> None:
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


async def _worker(runtime: Runtime, cmd: BringupCommand) -> BringupResult:
    try:
        result = await runtime.bringup(cmd)
    except RuntimeError as exc:
        raise ConflictError("worker", str(exc)) from exc
    if result.refused:
        raise ConflictError("hardware", result.message)
    return result


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
        _ensure_free(db, runtime)
        note = await _posture(runtime, script)
        result = await _worker(runtime, BringupCapture(seconds))
        profile = _draft_for(db, user, runtime)
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
        _ensure_free(db, runtime)
        note = await _posture(runtime, STANDING_SCRIPT)
        lay = _judging_layout(db)
        result = await _worker(runtime, BringupPulse(
            body.side, body.duration_ms / 1000.0, lay.offsets, lay.directions,
            calc.ALPHA_TOLERANCE_DEG))
        profile = _draft_for(db, user, runtime)
        return _store(db, user, profile, step, result.ok, result.message + note,
                      {"duration_ms": body.duration_ms, "solenoid_seen": result.solenoid_seen,
                       "released_seen": result.released_seen,
                       "samples": len(result.samples)})


async def watchdog(db: Session, user: User, runtime: Runtime,
                   body: WatchdogIn) -> StepResultOut:
    """Step e: energise one side, go silent, time the device's release."""
    _confirm(body.nobody_wearing)
    async with runtime.activity:
        _ensure_free(db, runtime)
        note = await _posture(runtime, STANDING_SCRIPT)
        lay = _judging_layout(db)
        result = await _worker(runtime, BringupWatchdog(
            body.side, lay.offsets, lay.directions, calc.ALPHA_TOLERANCE_DEG))
        profile = _draft_for(db, user, runtime)
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


async def link(db: Session, user: User, runtime: Runtime) -> StepResultOut:
    """Step f: the link's statistics as the worker reports them; passes while the
    device streams and nothing was dropped for authentication or as malformed."""
    async with runtime.activity:
        _ensure_free(db, runtime)
        h = runtime.health()
        profile = _draft_for(db, user, runtime)
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
        profile = draft(db)
        if profile is None:
            raise ConflictError("hardware", "no bring-up in progress: run a step first")
        missing = [s for s in STEP_NAMES if not profile.steps.get(s, {}).get("passed")]
        profile.firmware_version = firmware_version(runtime, body.firmware_version)
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
