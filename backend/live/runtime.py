"""The live path on the server: worker supervisor -> tick recorder and live stream.

Created by the app's lifespan; one per server process. The lifespan also attaches what
sits above the live path (the lab's LSL streams, the EMG inlets, the study's running
trials: `backend.live.parts`), so this module imports none of them.
"""

from __future__ import annotations

import asyncio
import logging
import subprocess
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from sqlalchemy import Engine

from backend import bootstrap
from backend.core.config import Settings
from backend.core.resources import version
from backend.live import device_process
from backend.live.device_binding import BoundDevice, mismatch
from backend.live.parts import LivePart, StudyHooks, TickListener
from backend.live.recorder import TickRecorder
from backend.live.solenoid_duty import SolenoidDuty
from backend.live.stream import LiveStream
from backend.schemas.live import (
    DatabaseHealth,
    DeviceHealth,
    DeviceReport,
    Health,
    LoopReport,
    WorkerHealth,
)
from backend.worker.device_gate import DeviceGate
from backend.worker.messages import (
    BringupCommand,
    BringupResult,
    CalibrationResult,
    CommandResult,
    RunStarted,
    TickBatch,
    Wearer,
    WorkerConfig,
)
from backend.worker.supervisor import WorkerBusyError as WorkerBusyError  # the routes' 409
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.config import ControllerConfig
from controller.controllers import registry
from controller.controllers.factory import needs_models
from controller.controllers.spec import ControllerSpec
from controller.decision.utility_function import UtilitySet
from controller.device.auth import load_or_create_key
from controller.device.base import DeviceIdentity
from controller.intent.motion_model import ModelSet
from controller.lowlevel.encoders import EncoderLayout

log = logging.getLogger(__name__)

#: The longest a command to a live worker may go unanswered. Not a guess at how long
#: the answer takes (every command is answered, in order with the ticks before it, and a
#: sped-up simulation never runs ahead of what the server stores): only a hung worker
#: reaches it. A worker that dies fails the wait at once, with its exit reason.
COMMAND_TIMEOUT_S = 120.0
#: A sped-up simulation waits while the recorder holds more ticks than this (a third of
#: its default backlog limit), at most `RECORDER_WAIT_S` per batch.
RECORDER_HOLD = 10_000
RECORDER_WAIT_S = 30.0


class WrongDeviceError(RuntimeError):
    """A controller was not started: the hardware profile in effect is not (or not yet
    shown to be) the device on the link's; the message says which is which."""


class Runtime:
    """Owns the worker, the recorder and the stream, and answers health questions."""

    def __init__(self, settings: Settings, engine: Engine) -> None:
        self.settings = settings
        host, port = settings.device_host_port
        self.calibration: CalibrationResult | None = None
        #: The simulated wearer (seed) the calibration was made on (`calibration_for`).
        self.calibration_seed: int | None = None
        self._calibration_waiters: dict[int, asyncio.Future[CalibrationResult]] = {}
        self._command_waiters: dict[int, asyncio.Future[CommandResult]] = {}
        self._bringup_waiters: dict[int, asyncio.Future[BringupResult]] = {}
        #: The hardware profile in effect (the latest completed one) with the device it
        #: is bound to; its layout applies only while that device is on the link
        #: (`encoder_layout`, docs/hardware-bringup.md).
        self.hardware_profile: tuple[int, BoundDevice, EncoderLayout] | None = None
        #: The solenoids' duty-cycle budget for bring-up steps.
        self.solenoid_duty = SolenoidDuty()
        self._run_ids: dict[int, int] = {}  # worker run token -> runs.id
        self._runs_started = 0
        self._last_run_token = 0
        self.worker_config = WorkerConfig(
            device_kind=settings.device_kind,
            device_host=host,
            device_port=port,
            device_seed=settings.device_seed,
            device_script=settings.device_script,
            device_key_file=str(settings.device_key_file),
            precompression_pct=settings.precompression_pct,
            device_speed=settings.device_speed,
            device_emg_lsl=settings.device_emg_lsl,
            models_path=str(settings.models_path),
        )
        self.recorder = TickRecorder(engine, settings.db_flush_interval,
                                     settings.db_backlog_limit)
        #: Held by every route that starts, stops or switches what the worker runs for
        #: the study (trials, recordings, controller, simulation, calibration): one at
        #: a time, so "is anything running?" and "start it" are one step.
        self.activity = asyncio.Lock()
        self.stream = LiveStream(settings.stream_rate, settings.stream_queue)
        #: Started and stopped with the live path (the lab's LSL streams, the EMG
        #: inlets), attached by the app factory.
        self.parts: list[LivePart] = []
        #: More consumers of the tick batches, runs and calibrations (the lab's LSL
        #: outlets and event markers), attached by the app factory.
        self.listeners: list[TickListener] = []
        #: The study this live path serves (the app factory's; none by default).
        self.study = StudyHooks()
        #: The default model and utility sets, once `start` has made sure they exist.
        self.defaults: tuple[ModelSet, UtilitySet] | None = None
        self.supervisor = WorkerSupervisor(
            self.worker_config,
            WorkerCallbacks(
                on_ticks=self._on_ticks,
                on_run_started=self._on_run_started,
                on_exit=self._on_exit,
                on_event=self._on_event,
                on_calibration=self._on_calibration,
                on_command_result=self._on_command_result,
                on_bringup=self._on_bringup,
            ),
        )
        self.device_process: subprocess.Popen[bytes] | None = None
        self._status_task: asyncio.Task[None] | None = None
        #: (key id, unique id) of the device last seen on the link (`_follow_identity`).
        self._seen_device: tuple[str, str] | None = None

    @property
    def hardware_is_simulated(self) -> bool:
        """Whether the device is one of the simulators (in process, or the device
        process this server spawns) rather than an exoskeleton on the network."""
        return self.settings.device_kind == "sim" or self.settings.device_spawn_simulator

    def load_hardware_layout(self) -> None:
        """Take the hardware profile in effect (the latest one completed), for real
        hardware only: a simulator keeps its own mounting, which a bring-up on a
        simulated wearer would otherwise shift by the wearer's standing posture
        (docs/hardware-bringup.md). Its layout applies only to the device it was made
        on (`encoder_layout`)."""
        from sqlalchemy import select
        from sqlalchemy.orm import Session

        from backend.db.hardware import HardwareProfile

        self.hardware_profile = None
        if self.hardware_is_simulated:
            return
        with Session(self.recorder.engine) as db:
            profile = db.scalars(select(HardwareProfile)
                                 .where(HardwareProfile.status == "complete")
                                 .order_by(HardwareProfile.id.desc()).limit(1)).first()
            if profile is not None:
                made_on = BoundDevice(profile.device, profile.key_id, profile.unique_id,
                                      profile.firmware_version)
                layout = EncoderLayout(tuple(profile.encoder_offsets),  # type: ignore[arg-type]
                                       tuple(profile.encoder_directions))  # type: ignore[arg-type]
                self.hardware_profile = (profile.id, made_on, layout)

    @property
    def device_identity(self) -> DeviceIdentity | None:
        """The identity the device proved on the link, as the worker last reported it
        (None before it joined, without a worker, and for the in-process simulator)."""
        status = self.supervisor.state.status
        return None if status is None or not self.supervisor.state.alive else status.identity

    def bound_device(self) -> BoundDevice | None:
        """The device on the link as profiles record it; None while a device on the
        link has not proved its identity yet."""
        kind = self.settings.device_kind
        if kind == "sim":
            return BoundDevice("sim", "", "", f"in-process simulator, ExoStudy {version()}")
        identity = self.device_identity
        if identity is None:
            return None
        return BoundDevice.of("udp-sim" if self.settings.device_spawn_simulator else "udp",
                              identity)

    def profile_verdict(self) -> str:
        """Why the profile in effect is not applied to the device on the link ("" when
        it is, or when there is none)."""
        if self.hardware_profile is None:
            return ""
        profile_id, made_on, _ = self.hardware_profile
        now = self.bound_device()
        if now is None:
            return (f"hardware profile {profile_id} is not applied yet: the device has not "
                    "proved its identity on the link")
        why = mismatch(made_on, now)
        if why:
            return (f"hardware profile {profile_id} is refused on this device ({why}): "
                    f"this is {now.describe()}; run the bring-up again on it")
        return ""

    @property
    def encoder_layout(self) -> EncoderLayout | None:
        """The encoder layout every controller decodes counts with: the profile in
        effect's, while the device it was made on is on the link; None (the default
        layout, the simulator's own mounting) otherwise."""
        if self.hardware_profile is None or self.profile_verdict():
            return None
        return self.hardware_profile[2]

    def utilities_path(self) -> Path:
        """The default utility set for the configured precompression."""
        return bootstrap.utilities_path(self.settings.utilities_dir,
                                        self.settings.precompression_pct)

    def prepare_defaults(self) -> tuple[ModelSet, UtilitySet]:
        """Build the default model and utility sets if they are missing (first start);
        the sets (the app factory builds the demo study from them)."""
        models = bootstrap.ensure_models(self.settings.models_path)
        utilities = bootstrap.ensure_utilities(self.utilities_path(),
                                               self.settings.precompression_pct)
        return models, utilities

    def calibration_for(self, seed: int | None = None) -> CalibrationResult | None:
        """The E-UMC calibration, if it applies to the wearer on the device, or to the
        simulated wearer `seed` a trial is about to put on. A calibration is per donning:
        on a simulator it belongs to the virtual participant it was made on (standing hip
        angles differ by up to about 12 deg between them), and another has none."""
        cal = self.calibration
        if cal is None or not cal.ok:
            return None
        if self.hardware_is_simulated:
            wearer = self.settings.device_seed if seed is None else seed
            if wearer != self.calibration_seed:
                return None
        return cal

    def controller_spec(
        self, name: str, overrides: dict[str, Any] | None = None,
        wearer_seed: int | None = None,
    ) -> ControllerSpec:
        """The one place the server builds a controller's configuration: defaults, the
        server's settings, the E-UMC calibration if one was made, then `overrides`
        (settings fields), with the default model and utility files; `wearer_seed`: the
        simulated wearer the controller will run on, if not the present one. Raises
        SettingError naming the field (refused here, not in the worker)."""
        cfg = ControllerConfig(precompression_pct=self.settings.precompression_pct)
        if self.settings.controller_rate_hz is not None:
            cfg = cfg.at_rate(self.settings.controller_rate_hz)
        settings: dict[str, Any] = cfg.to_json()
        if self.encoder_layout is not None:
            settings["encoder_offsets"] = list(self.encoder_layout.offsets)
            settings["encoder_directions"] = list(self.encoder_layout.directions)
        cal = self.calibration_for(wearer_seed)
        if registry.needs_calibration(name) and cal is not None:
            settings["calibration"] = [cal.offset_left, cal.offset_right]
        settings.update(overrides or {})
        return ControllerSpec(
            name, ControllerConfig.from_json(settings),
            models_path=str(self.settings.models_path) if needs_models(name) else None,
            utilities_path=str(self.utilities_path()) if needs_models(name) else None)

    def device_gate(self, spec: ControllerSpec) -> DeviceGate | None:
        """The device `spec` may run on, for the worker to hold it to: None for `none`
        and while no hardware profile is in effect (the default layout, any device).
        Raises WrongDeviceError while the device on the link has not proved to be the
        profile's, and when `spec` was built with another layout than the profile's
        (the device changed while it was being built)."""
        if spec.name == registry.idle() or self.hardware_profile is None:
            return None
        profile_id, made_on, layout = self.hardware_profile
        verdict = self.profile_verdict()
        if verdict:
            raise WrongDeviceError(f"controller {spec.name!r} not started: {verdict}")
        if (tuple(spec.settings.encoder_offsets) != tuple(layout.offsets)
                or tuple(spec.settings.encoder_directions) != tuple(layout.directions)):
            raise WrongDeviceError(f"controller {spec.name!r} not started: its encoder layout is "
                              f"not hardware profile {profile_id}'s (the device on the "
                              "link changed while it was being built, or the request "
                              "overrides the layout)")
        return DeviceGate(profile_id, made_on.key_id, made_on.unique_id)

    def set_controller(self, name: str, overrides: dict[str, Any] | None = None) -> None:
        """Switch the worker's controller (a new run starts). Raises WrongDeviceError (see
        `device_gate`)."""
        spec = self.controller_spec(name, overrides)
        self.supervisor.set_controller(spec, device=self.device_gate(spec))

    def release(self) -> None:
        """Back to controller `none` without waiting: nothing locks until a new switch
        (what a refused or failed start leaves the worker with)."""
        self.supervisor.set_controller(self.controller_spec(registry.idle()))

    async def switch_controller(
        self, spec: ControllerSpec, timeout: float = COMMAND_TIMEOUT_S,
        max_ticks: int | None = None, wearer: Wearer | None = None,
    ) -> int:
        """Switch to the validated `spec` and wait until the worker runs it; returns the
        new run's id. With `max_ticks` the worker ends the run by itself after that many
        samples; with `wearer` (the in-process simulator only, its script checked by the
        caller) the run starts with that simulated wearer's first sample. Raises
        RuntimeError if the worker is down or refuses (with the worker's reason)."""
        name = spec.name
        if not self.supervisor.state.alive:
            raise RuntimeError("the worker is not running: restart it first")
        gate = self.device_gate(spec)
        fut = self._command_future()
        rid = self.supervisor.set_controller(spec, max_ticks, gate, wearer)
        answer = await self._answer(rid, fut, f"start {name}", timeout)
        if not answer.ok:
            raise RuntimeError(answer.message)
        run_id = self._run_ids.get(answer.run_token)
        if run_id is None:
            # The worker runs it, but the database refused its run's row: nothing may run
            # that the study cannot record (its ticks would be dropped, and a trial or
            # recording would have no run, or another's).
            self.release()
            raise RuntimeError(f"{name} not started: its run could not be stored "
                               f"({self.recorder.last_error or 'the database refused it'})"
                               "; the worker is back to none")
        return run_id

    async def idle(self) -> None:
        """Back to controller `none` (a new run, no locks) if the worker is alive; a
        worker that died meanwhile has already stored its ticks and closed its run."""
        if not self.supervisor.state.alive:
            return
        try:
            await self.switch_controller(self.controller_spec(registry.idle()))
        except RuntimeError:
            pass

    def _command_future(self) -> asyncio.Future[CommandResult]:
        return asyncio.get_running_loop().create_future()

    async def _answer(self, rid: int, fut: asyncio.Future[CommandResult], what: str,
                      timeout: float) -> CommandResult:
        """The worker's answer to request `rid`; RuntimeError if it dies first."""
        if not rid:
            raise RuntimeError(f"the worker is not running: it cannot {what}")
        self._command_waiters[rid] = fut
        try:
            return await self._until_answered(fut, what, timeout)
        finally:
            self._command_waiters.pop(rid, None)

    async def _until_answered(self, fut: asyncio.Future[Any], what: str,
                              timeout: float) -> Any:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while not fut.done():
            if not self.supervisor.state.alive:
                reason = self.supervisor.state.exit_reason or "exited"
                raise RuntimeError(f"the worker stopped ({reason}) before it could {what}")
            if loop.time() > deadline:
                raise RuntimeError(f"the worker did not answer within {timeout:.0f} s: "
                                   f"it could not {what}")
            await asyncio.wait([fut], timeout=0.1)
        return fut.result()

    def _on_command_result(self, result: CommandResult) -> None:
        def resolve() -> None:
            # Looked up on the event loop, where the waiter registers right after the
            # send: an answer faster than that registration is still delivered.
            fut = self._command_waiters.get(result.request_id)
            if fut is not None and not fut.done():
                fut.set_result(result)

        self.stream.call_soon(resolve)

    async def set_simulation(self, seed: int, script: str, speed: float | None = None,
                             max_ticks: int | None = None) -> int | None:
        """Put another virtual participant (seed) or script on the simulated device: the
        worker swaps its in-process simulator (a new run, same process), or the device
        process (UDP) restarts. The current controller is kept, with a fresh state.
        Returns the id of the run the swapped simulator starts with (its first sample is
        the script's first; with `max_ticks` it holds that many samples, in-process
        simulator only), None when the worker or the device process restarted."""
        from controller.sim.scripts import get_script

        try:
            get_script(script)
        except ValueError as exc:
            raise ValueError(f"script: {exc}") from exc  # names the valid scripts
        if speed is not None and self.settings.device_kind != "sim":
            raise ValueError("speed: only the in-process simulator (device_kind 'sim') runs "
                             "faster than real time")
        speed = self.supervisor.config.device_speed if speed is None else speed
        runs_before = self._runs_started
        run_id: int | None = None
        if self.settings.device_kind == "sim":
            # The running worker swaps its simulated device (no process start); a worker
            # that is down picks the new configuration up when it starts. Either way the
            # record of the wearer follows the worker's new run (`_on_run_started`).
            fut = self._command_future()
            rid = self.supervisor.set_simulation(seed, script, speed, max_ticks)
            if rid is None:
                await asyncio.to_thread(self.supervisor.restart)
            else:
                answer = await self._answer(rid, fut, "change the simulation",
                                            COMMAND_TIMEOUT_S)
                if not answer.ok:
                    raise RuntimeError(answer.message)
                run_id = self._run_ids.get(answer.run_token)
        elif self.settings.device_spawn_simulator:
            # The device process starts from these settings.
            self.settings = self.settings.model_copy(update={
                "device_seed": seed, "device_script": script, "device_speed": speed})
            self.worker_config = replace(self.supervisor.config, device_seed=seed,
                                         device_script=script, device_speed=speed)
            self.supervisor.config = self.worker_config
            if self.device_process is not None:
                await asyncio.to_thread(device_process.stop, self.device_process,
                                        self._device_pid_file())
                self.device_process = None
            await asyncio.to_thread(self.start_device_simulator)
        else:
            raise ValueError("device: the device is real hardware: there is no simulation "
                             "to change")
        # Return only once the new simulation streams: a recording or trial started
        # before that would attach to a run that is about to be replaced.
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 60.0
        while loop.time() < deadline:
            st = self.supervisor.state.status
            restarted = (self.settings.device_kind != "sim"
                         or self._runs_started > runs_before)
            # A status of the run announced last is the new simulation's (the worker
            # reports one at the new wearer's first sample, so this takes milliseconds,
            # and a recording started next misses little of the script); the supervisor
            # clears `status` when the device process restarts.
            current = st is not None and (self.settings.device_kind != "sim"
                                          or st.run_token == self._last_run_token)
            if restarted and current and st is not None and st.device.alive \
                    and self.supervisor.state.alive:
                return run_id
            await asyncio.sleep(0.05)
        raise RuntimeError("the simulated device did not start streaming again")

    async def calibrate(self, seconds: float, max_std_deg: float) -> CalibrationResult:
        """Ask the worker to calibrate and wait for the outcome."""
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[CalibrationResult] = loop.create_future()
        rid = self.supervisor.request_calibration(seconds, max_std_deg)
        self._calibration_waiters[rid] = fut
        try:
            # Answered after `seconds` of samples, or abandoned with a reason.
            result: CalibrationResult = await self._until_answered(
                fut, "calibrate", COMMAND_TIMEOUT_S + seconds)
            return result
        finally:
            self._calibration_waiters.pop(rid, None)

    async def bringup(self, cmd: BringupCommand) -> BringupResult:
        """Send a hardware bring-up command to the worker and wait for its answer
        (RuntimeError if the worker is down or dies first)."""
        if not self.supervisor.state.alive:
            raise RuntimeError("the worker is not running: restart it first")
        fut: asyncio.Future[BringupResult] = asyncio.get_running_loop().create_future()
        rid = self.supervisor.request_bringup(cmd)
        self._bringup_waiters[rid] = fut
        try:
            result: BringupResult = await self._until_answered(
                fut, "run the bring-up step", COMMAND_TIMEOUT_S)
            return result
        finally:
            self._bringup_waiters.pop(rid, None)

    def _on_bringup(self, result: BringupResult) -> None:
        def resolve() -> None:
            fut = self._bringup_waiters.get(result.request_id)
            if fut is not None and not fut.done():
                fut.set_result(result)

        self.stream.call_soon(resolve)

    def _on_calibration(self, result: CalibrationResult) -> None:
        for listener in self.listeners:
            listener.on_calibration(result.ok, result.message)
        if result.ok:
            self.calibration = result
            self.calibration_seed = self.settings.device_seed

        def resolve() -> None:
            fut = self._calibration_waiters.get(result.request_id)
            if fut is not None and not fut.done():
                fut.set_result(result)

        self.stream.call_soon(resolve)

    async def start(self) -> None:
        """Start recording, streaming and (if configured) the device simulator and worker."""
        self.defaults = await asyncio.to_thread(self.prepare_defaults)
        await asyncio.to_thread(self.load_hardware_layout)
        self.worker_config = replace(
            self.worker_config,
            spec=self.controller_spec(self.settings.controller),
        )
        self.supervisor.config = self.worker_config
        self.recorder.start()
        await self.stream.start()
        for part in self.parts:
            part.start()
        if self.settings.device_kind == "udp":
            # First start: a new link key, private to this user (mode 0600).
            load_or_create_key(self.settings.device_key_file)
        if self.settings.device_kind == "udp" and self.settings.device_spawn_simulator:
            try:
                self.start_device_simulator()
            except device_process.DeviceStartError as exc:
                # The server still starts (health shows the device down and why); the
                # worker retries the address until a device answers.
                log.error("%s", exc)
                self.supervisor.state.errors.append(str(exc))
        if self.settings.start_worker:
            self.supervisor.start()
        self._status_task = asyncio.create_task(self._status_loop(), name="status-loop")

    async def _status_loop(self) -> None:
        # Consoles learn of a dead worker within 0.1 s through on_exit; this periodic
        # message keeps their timing figures current.
        while True:
            await asyncio.sleep(1.0)
            try:
                await self._follow_identity()
            except Exception:
                log.exception("re-resolving the encoder layout for a new device failed")
            if self.stream.client_count:
                self._on_event("tick", {})

    async def _follow_identity(self) -> None:
        """When the device on the link first proves its identity, or another device
        appears, the idle worker's `none` is started again so that it decodes with the
        layout that applies to this device (the profile's, or the default one). A
        controller that locks is held to its device by the worker itself (it stops,
        released, on another device: `backend.worker.device_gate`)."""
        identity = self.device_identity
        if identity is None:
            return
        seen = (identity.key_id, identity.unique_id)
        if seen == self._seen_device:
            return
        self._seen_device = seen
        if self.hardware_profile is None:
            return  # nothing to re-resolve: the default layout applies to any device
        async with self.activity:
            busy = self.study.running()
            if busy is None and self.supervisor.config.controller == registry.idle():
                await self.idle()

    async def stop(self) -> None:
        """Stop the worker first (it releases the device), then flush and close."""
        if self._status_task is not None:
            self._status_task.cancel()
        self.supervisor.stop("server shutdown")
        self.recorder.worker_exited("server shutdown")
        self.recorder.stop()
        await self.stream.stop()
        for part in reversed(self.parts):
            part.stop()
        if self.device_process is not None:
            device_process.stop(self.device_process, self._device_pid_file())

    def _device_pid_file(self) -> Path:
        return self.settings.run_dir / f"device-sim-{self.settings.device_host_port[1]}.pid"

    def start_device_simulator(self) -> None:
        """Run the simulated exoskeleton as its own process on the device address (the
        Python or the C device, setting `device_implementation`), after stopping one an
        earlier server left there; returns once it holds the port.
        Raises `device_process.DeviceStartError` (with the reason) if it cannot."""
        host, port = self.settings.device_host_port
        pid_file = self._device_pid_file()
        stale = device_process.reclaim(pid_file, port)
        if stale is not None:
            log.warning("stopped device simulator %d left by an earlier server", stale)
        cmd = [
            "--port", str(port), "--seed", str(self.settings.device_seed),
            "--script", self.settings.device_script,
            "--precompression", str(self.settings.precompression_pct),
            "--bind", host,
            # The only address the device takes commands from: this machine's worker.
            "--host", "127.0.0.1" if host in ("127.0.0.1", "localhost") else host,
            "--key-file", str(self.settings.device_key_file),
            # Real-time scheduling where allowed (root or CAP_SYS_NICE), as the worker's
            # loop has: the simulator stands in for firmware on its own board. Normally
            # scheduled, it stalled behind the server's start-up and judged the worker's
            # prompt answers stale when it read them (`device_stale`, ~15 at a start).
            "--realtime",
        ]
        self.device_process = device_process.spawn(
            cmd, port, pid_file, self.settings.run_dir / f"device-sim-{port}.log",
            implementation=self.settings.device_implementation)

    # Supervisor callbacks (reader thread).
    def _on_ticks(self, batch: TickBatch) -> None:
        self.recorder.add(batch)
        self.stream.push(batch.ticks)
        for listener in self.listeners:
            listener.on_ticks(batch)
        if self.supervisor.config.device_speed > 1.0:
            self._wait_for_recorder()

    def _wait_for_recorder(self) -> None:
        """A sped-up simulation is paced by what the database stores: while the
        recorder's backlog is high this (reader) thread waits, the pipe fills and the
        worker holds its simulated device (see `backend.worker.process._hold`), so a
        slow disk or a loaded machine slows the simulation instead of dropping ticks.
        Bounded, so a database that refuses writes for long ends in the recorder's
        counted drops, as for a real-time device."""
        deadline = time.monotonic() + RECORDER_WAIT_S
        while (self.recorder.backlog > RECORDER_HOLD and self.supervisor.state.alive
               and time.monotonic() < deadline):
            time.sleep(0.01)

    def _on_run_started(self, msg: RunStarted) -> None:
        w = msg.wearer
        if w is not None and w.speed is not None:
            # The wearer as the worker runs it and the speed asked for it (the
            # supervisor's configuration follows them too): never a wearer a refused
            # request named.
            self.settings = self.settings.model_copy(update={
                "device_seed": w.seed, "device_script": w.script, "device_speed": w.speed})
            self.worker_config = self.supervisor.config
        try:
            run_id = self.recorder.run_started(msg, msg.device_kind)
        except Exception as exc:
            # Its ticks are dropped and counted (an unknown run token); a start waiting
            # for this run is refused and the worker released (`switch_controller`).
            self.recorder.last_error = f"storing a new run failed: {exc}"[:300]
            log.exception("storing run %s of the worker failed", msg.run_token)
            return
        for listener in self.listeners:
            listener.on_run_started(msg.run_token, run_id)
        self.stream.run_id = run_id
        self._run_ids[msg.run_token] = run_id
        self._runs_started += 1
        self._last_run_token = msg.run_token
        self._on_event("run", {"run_id": run_id, "controller": msg.controller})

    def _on_exit(self, code: int | None, reason: str) -> None:
        # A new worker numbers its runs from 1 again: none of this one's tokens may name
        # a run of the next (a run the database refused to store would otherwise be
        # answered with an old run's id).
        self._run_ids.clear()
        # Everything the worker sent is stored and its run closed first, so the trial
        # it ran is closed with its real tick count.
        try:
            self.recorder.worker_exited(reason)
        except Exception:
            log.exception("closing the run of the exited worker failed")
        try:
            closed = self.study.interrupt_running(f"the worker stopped: {reason}")
        except Exception:
            log.exception("closing what the exited worker ran failed")
            return
        if closed:
            log.warning("worker stopped (%s): %s interrupted", reason, ", ".join(closed))

    def _on_event(self, kind: str, data: dict[str, Any]) -> None:
        self.stream.broadcast_json({"type": "status", "health": self.health().model_dump()})

    def health(self) -> Health:
        """The state of the live path, as `GET /api/health` reports it."""
        st = self.supervisor.state
        s = st.status
        status_fresh = st.alive and st.status_at is not None and time.time() - st.status_at < 1.5
        # The worker's own reports, shown as they arrived (one definition, no mapping).
        loop = s.loop if s else LoopReport(controller=self.supervisor.config.controller)
        worker = WorkerHealth(**loop.model_dump(), alive=st.alive,
                              pid=st.pid if st.alive else None, restarts=st.restarts,
                              exit_code=st.exit_code, exit_reason=st.exit_reason,
                              errors=list(st.errors[-5:]))
        report = s.device if s else DeviceReport(alive=False)
        device = DeviceHealth(**report.model_dump(exclude={"alive"}),
                              alive=bool(status_fresh and report.alive),
                              kind=self.settings.device_kind,
                              identity=s.identity if s else None)
        db = DatabaseHealth(
            ticks_written=self.recorder.written,
            write_failures=self.recorder.failures,
            last_error=self.recorder.last_error,
            current_run_id=self.recorder.current_run_id,
            backlog=self.recorder.backlog,
            ticks_dropped=self.recorder.dropped,
        )
        ok = worker.alive and device.alive and not self.recorder.last_error
        return Health(
            status="ok" if ok else "degraded",
            worker=worker,
            device=device,
            database=db,
            clients=self.stream.client_count,
        )
