"""The worker as a state machine: which commands each state takes, and how it leaves.

The lock command is the only output that touches the wearer (docs/trial-states.md), so
the worker's states say when a lock is possible and the tables below say how each state
may be left. Two rules are checked by `Machine.go` on every transition:

- every way out of a state in which the device may lock (`LOCKING`) to one in which it
  may not passes through `RELEASING`, which tells the device to let go;
- a command a state does not take is refused with a reason, and the refusal is answered
  (the server waits for every answer; see docs/worker-commands.md).

A calibration is not a state: it is a job (`CalibrationJob`) that collects the next
seconds of ticks beside whatever the worker is doing (idle or a controller without a time
limit), with its own short table of what it refuses while it runs (`WHILE_CALIBRATING`).

`Machine.run` is the 100 Hz loop: one tick per device sample, the commands that arrived
in between dispatched through `Machine.handlers`, a table keyed by the command's kind
(its type, or `BringupCommand` for the four bring-up steps, which share every rule).
"""

from __future__ import annotations

import dataclasses
import enum
import gc
import math
import os
import select
import time
from collections.abc import Callable
from dataclasses import replace
from multiprocessing.connection import Connection
from types import UnionType
from typing import Any

import numpy as np

from backend.schemas.live import DeviceReport, LoopReport
from backend.worker import bringup
from backend.worker.child_processes import ParentWatch
from backend.worker.device_gate import DeviceGate
from backend.worker.devices import make_device
from backend.worker.messages import (
    BringupCommand,
    BringupResult,
    Calibrate,
    CalibrationResult,
    CommandResult,
    RunStarted,
    SetController,
    SetSimulation,
    StopWorker,
    Wearer,
    WorkerCommand,
    WorkerConfig,
    WorkerError,
    WorkerMessage,
    WorkerStatus,
)
from backend.worker.outbox import Outbox
from backend.worker.scheduling import loop_scheduling, paced
from controller.controllers import registry
from controller.controllers.factory import load_models, make_from_spec
from controller.controllers.registry import needs_calibration
from controller.controllers.spec import ControllerSpec
from controller.device.base import SAMPLE_PERIOD_S, Device
from controller.intent.calibration import CalibrationError, calibrate
from controller.interface import Controller
from controller.runner.loop import ControlLoop
from controller.stop_flag import SignalSafeFlag
from controller.tick_record import TickRecord

#: A sped-up simulation (device time is virtual) waits while more records than this are
#: queued for the server, and resumes below `BACKLOG_RESUME`: the worker never produces
#: faster than the server stores, so nothing is dropped and a command's answer is never
#: stuck behind seconds of queued ticks on a loaded machine. 1,000 records are 0.125 s
#: of an 80x simulation; a real-time device never waits (it cannot).
BACKLOG_HOLD = 1000
BACKLOG_RESUME = 250
#: How often the loop asks whether the server is still there: once a sample period.
#: Asking at every tick of a sped-up simulation cost a twentieth of the worker's CPU.
PARENT_CHECK_S = SAMPLE_PERIOD_S


def _resting() -> str:
    """The controller that never locks (`none`): what the worker falls back to."""
    return registry.idle()


def _is_resting(name: str) -> bool:
    reg = registry.lookup(name)
    return reg is not None and reg.idle


class State(enum.Enum):
    """What the worker is doing, as far as the wearer is concerned."""

    #: Controller `none`: nothing can lock.
    IDLE = "idle"
    #: A controller chosen by the experimenter, without a time limit (live page,
    #: recordings): it may lock.
    CONTROLLING = "controlling"
    #: A timed run (`SetController.max_ticks`, a trial): ends by itself, back to `none`.
    TRIAL = "trial"
    #: A hardware bring-up step owns the device (it may energise a solenoid).
    BRINGUP = "bringup"
    #: The device is told to let go (passed through, never stayed in).
    RELEASING = "releasing"
    #: The loop ends; the device is released and closed.
    STOPPING = "stopping"


#: States in which the device may be commanded to lock.
LOCKING = frozenset({State.CONTROLLING, State.TRIAL, State.BRINGUP})

#: Every transition the worker may make. Leaving a locking state for one that cannot
#: lock goes through RELEASING, and so does every way to STOPPING; a locking state may
#: hand over to another one directly (a new controller decides at the next sample).
EDGES: frozenset[tuple[State, State]] = frozenset({
    (State.IDLE, State.CONTROLLING), (State.IDLE, State.TRIAL),
    (State.IDLE, State.BRINGUP), (State.IDLE, State.RELEASING),
    (State.CONTROLLING, State.TRIAL), (State.CONTROLLING, State.RELEASING),
    (State.TRIAL, State.RELEASING),
    (State.BRINGUP, State.RELEASING),
    (State.RELEASING, State.IDLE), (State.RELEASING, State.CONTROLLING),
    (State.RELEASING, State.STOPPING),
})

#: What the tables are keyed on: a command's type, or the union of the bring-up steps
#: (`BringupCommand`: the four share every rule, handler and answer).
Kind = type | UnionType
#: Every kind of command, in the order `kind_of` tries them.
KINDS: tuple[Kind, ...] = (SetController, SetSimulation, Calibrate, StopWorker, BringupCommand)
#: A state's rule for a kind: None (taken), a reason (refused), or a check of the command
#: in context that gives a reason, or "" to take it.
Rule = str | Callable[["Machine", Any], str] | None

_TRIAL_RUNS = "a timed trial is running"


def kind_of(cmd: object) -> Kind | None:
    """The kind the tables know `cmd` by; None for something that is not a command."""
    return next((k for k in KINDS if isinstance(cmd, k)), None)


def _needs_none(m: Machine, _cmd: BringupCommand) -> str:
    """Bring-up steps energise solenoids themselves: only with no controller running."""
    return f"controller {m.spec.name!r} is running: bring-up needs {_resting()!r}"


def _only_release(_m: Machine, cmd: SetController) -> str:
    """A trial's run is replaced by nothing but `none` (its stop), on the same wearer."""
    if _is_resting(cmd.spec.name) and cmd.max_ticks is None and cmd.wearer is None:
        return ""
    return f"{_TRIAL_RUNS}: only {_resting()!r} may replace its controller (stop it first)"


def _no_trial_while_calibrating(_m: Machine, cmd: SetController) -> str:
    return "" if cmd.max_ticks is None else \
        "a calibration is being collected: a timed trial cannot start now"


def _simulated(m: Machine, _cmd: WorkerCommand) -> str:
    if m.config.device_kind == "sim":
        return ""
    return "the device is not the in-process simulator: there is no simulation to change"


def _wearer_needs_simulator(m: Machine, cmd: SetController) -> str:
    """A controller with a new simulated wearer: only on the in-process simulator."""
    return "" if cmd.wearer is None else _simulated(m, cmd)


#: Which kinds of command each state takes (see `Rule`). States not listed take no
#: command (RELEASING, BRINGUP and STOPPING are passed through inside one handler).
RULES: dict[State, dict[Kind, Rule]] = {
    State.IDLE: {
        SetController: _wearer_needs_simulator, SetSimulation: _simulated, Calibrate: None,
        BringupCommand: None, StopWorker: None,
    },
    State.CONTROLLING: {
        SetController: _wearer_needs_simulator, SetSimulation: _simulated, Calibrate: None,
        BringupCommand: _needs_none, StopWorker: None,
    },
    State.TRIAL: {
        SetController: _only_release,
        SetSimulation: f"{_TRIAL_RUNS}: the simulated wearer cannot change under it",
        Calibrate: f"{_TRIAL_RUNS}: a calibration would change its controller",
        BringupCommand: f"{_TRIAL_RUNS}: bring-up needs the worker idle", StopWorker: None,
    },
}

#: What a calibration being collected refuses besides its state's rules (kinds not
#: listed are left to the state: a new wearer or a bring-up step abandons it, with an
#: answer; a controller without a time limit takes over beside it).
WHILE_CALIBRATING: dict[Kind, Rule] = {
    Calibrate: "a calibration is already being collected",
    SetController: _no_trial_while_calibrating,
}


def _verdict(rule: Rule, m: Machine, cmd: WorkerCommand) -> str:
    if rule is None or isinstance(rule, str):
        return rule or ""
    return rule(m, cmd)


def refusal(m: Machine, cmd: WorkerCommand) -> str:
    """Why the machine in its present state, and its calibration if one is being
    collected, does not take `cmd` ("" if it does)."""
    rules, kind = RULES.get(m.state, {}), kind_of(cmd)
    if kind is None or kind not in rules:
        return f"the worker is {m.state.value}: it takes no {type(cmd).__name__}"
    why = _verdict(rules[kind], m, cmd)
    if not why and m.calibration is not None:
        why = _verdict(WHILE_CALIBRATING.get(kind), m, cmd)
    return why


def _refused_change(cmd: SetController | SetSimulation, reason: str
                    ) -> tuple[WorkerMessage, ...]:
    """Shown to the experimenter, and the answer its sender waits for (if one does)."""
    answer = (CommandResult(cmd.request_id, False, reason),) if cmd.request_id else ()
    return (WorkerError(reason), *answer)


#: How a refused command is answered, by kind: in the form its sender waits for.
#: Anything else (StopWorker is never refused; something that is not a command at all)
#: is reported as a `WorkerError`: nobody waits, the experimenter sees it.
REFUSALS: dict[Kind, Callable[[Any, str], tuple[WorkerMessage, ...]]] = {
    Calibrate: lambda cmd, why: (CalibrationResult(cmd.request_id, False, why),),
    BringupCommand: lambda cmd, why: (BringupResult(cmd.request_id, False, why,
                                                    refused=True),),
    SetController: _refused_change,
    SetSimulation: _refused_change,
}


def let_go(device: Device) -> None:
    """The one way the worker lets a device go at its end: release (no solenoid stays
    energised), then close; a device that fails to close is already released."""
    device.release()
    try:
        device.close()
    except Exception:
        pass


def build(spec: ControllerSpec) -> Controller:
    """The one place the worker builds a controller. The specification is validated
    again first (it crossed a process boundary: unpickling does not run the checks),
    then built through the registry and warmed up, so its first tick is not slow."""
    checked = replace(spec, settings=replace(spec.settings))
    controller = make_from_spec(checked)
    controller.warm_up()
    return controller


class TransitionError(RuntimeError):
    """A transition missing from `EDGES`: a bug, which ends the worker released."""


class Runs:
    """The worker's current run, and the one way a new one starts.

    A run is what the server stores ticks under: every change of controller, wearer or
    configuration starts one, announced by `RunStarted` before any of its ticks (the
    outbox sends the ticks queued before it under the old token first)."""

    def __init__(self, outbox: Outbox, pid: int,
                 wearer: Callable[[], Wearer | None] = lambda: None) -> None:
        self.outbox, self.pid, self.wearer = outbox, pid, wearer
        self.token = 0
        self.ticks = 0  # samples of the current run
        self.limit: int | None = None  # a timed run ends by itself after this many

    def start(self, spec: ControllerSpec, device_kind: str, limit: int | None = None,
              *, count_again: bool = True) -> int:
        """Announce a new run of `spec`; its token. With `count_again=False` the sample
        count and limit carry over (a calibration applied to the running controller)."""
        self.token += 1
        reached = (self.ticks if self.limit is not None and self.ticks >= self.limit
                   else None)
        if count_again:
            self.ticks, self.limit = 0, limit
        self.outbox.put(RunStarted(self.token, spec.name, spec.to_config(), device_kind,
                                   self.pid, self.wearer(), reached))
        self.outbox.run_token = self.token
        return self.token


class Machine:
    """The worker's device, controller, run and state, and one handler per command."""

    def __init__(self, config: WorkerConfig, device: Device, outbox: Outbox,
                 cmd_conn: Connection, parent: ParentWatch, stopping: SignalSafeFlag) -> None:
        self.config, self.device, self.outbox = config, device, outbox
        self.cmd_conn, self.parent, self.stopping = cmd_conn, parent, stopping
        self.pid = os.getpid()
        self.state = State.IDLE
        #: Every state entered, in order (the tests read the transitions from it).
        self.trace: list[State] = [State.IDLE]
        self.exit_code = 0
        #: The calibration being collected beside the running controller, if any.
        self.calibration: CalibrationJob | None = None
        self.runs = Runs(outbox, self.pid, self._wearer)
        self.next_status = time.monotonic()
        #: The device the running controller's encoder layout belongs to (None: no
        #: hardware profile, any device); see `backend.worker.device_gate`.
        self.gate: DeviceGate | None = None
        #: One handler per kind of command: the rules have already taken it.
        self.handlers: dict[Kind, Callable[[Any], None]] = {
            SetController: self.on_set_controller,
            SetSimulation: self.on_set_simulation,
            Calibrate: self.on_calibrate,
            BringupCommand: self.on_bringup,
            StopWorker: self.on_stop,
        }
        try:
            controller, self.spec = build(config.spec), config.spec
        except Exception as exc:
            outbox.put(WorkerError(f"controller {config.spec.name!r}: {exc}; using "
                                   f"{_resting()!r}"))
            self.spec = ControllerSpec(_resting())
            controller = build(self.spec)
        self.loop = self._new_loop(controller)
        target = self._target(self.spec, None)
        if target is not State.IDLE:
            self.go(target)
        self.runs.start(self.spec, device.kind)

    # -- transitions -----------------------------------------------------------------

    def go(self, to: State) -> None:
        """Enter `to`, if `EDGES` allows it from here (TransitionError if not)."""
        if (self.state, to) not in EDGES:
            raise TransitionError(f"no transition from {self.state.value} to {to.value}")
        if to is State.RELEASING:
            self.device.release()
        self.state = to
        self.trace.append(to)

    def leave_for(self, to: State) -> None:
        """Go to `to`, through RELEASING when the device may be locking now."""
        if self.state is not State.RELEASING and (self.state in LOCKING
                                                  or to is State.STOPPING):
            self.go(State.RELEASING)
        if self.state is not to:
            self.go(to)

    @staticmethod
    def _target(spec: ControllerSpec, max_ticks: int | None) -> State:
        if max_ticks is not None:
            return State.TRIAL
        return State.IDLE if _is_resting(spec.name) else State.CONTROLLING

    def _new_loop(self, controller: Controller) -> ControlLoop:
        """A control loop on the current device whose locks pass the device gate."""
        loop = ControlLoop(self.device, controller)
        loop.lock_gate = self._gate_refusal
        return loop

    def _gate_refusal(self) -> str:
        """Why the running controller may not lock the device on the link now ("" if
        it may): its encoder layout belongs to another device, or to a device that has
        not proved its identity since the link (re)joined."""
        gate = self.gate
        return "" if gate is None else gate.refusal(self.device.identity)

    def _run(self, controller: Controller, spec: ControllerSpec, to: State,
             max_ticks: int | None = None, gate: DeviceGate | None = None) -> int:
        """Run `controller` (built from `spec`) in state `to`, as a new run; its token.
        `gate`: the device its layout belongs to (kept only for a controller that
        locks)."""
        self.gate = None if _is_resting(spec.name) else gate
        if to is State.IDLE:
            self.leave_for(to)
        elif to is not self.state:
            self.go(to)
        self.loop.controller, self.spec = controller, spec
        # A "no exoskeleton" baseline: a simulated wearer gets no exoskeleton torque
        # (devices without `wear` are real: the experimenter takes the device off).
        wear = getattr(self.device, "wear", None)
        if callable(wear):
            wear(registry.exoskeleton_worn(spec.name))
        return self.runs.start(spec, self.device.kind, max_ticks)

    def _fall_back(self) -> int:
        """Back to `none`, released, as a new run; its token."""
        resting = ControllerSpec(_resting())
        return self._run(build(resting), resting, State.IDLE)

    # -- commands ----------------------------------------------------------------------

    def dispatch(self, cmd: WorkerCommand) -> None:
        """Hand `cmd` to its handler, or answer why this state does not take it."""
        reason = refusal(self, cmd)
        if reason:
            self.refuse(cmd, reason)
            return
        kind = kind_of(cmd)
        assert kind is not None  # `refusal` refuses what is not a command
        self.handlers[kind](cmd)

    def refuse(self, cmd: object, reason: str) -> None:
        """Answer a refused command in the form its sender waits for (`REFUSALS`)."""
        kind = kind_of(cmd)
        answer = REFUSALS.get(kind) if kind is not None else None
        for msg in answer(cmd, reason) if answer else (WorkerError(reason),):
            self.outbox.put(msg)

    def answer(self, request_id: int, refused: str, run_token: int = 0) -> None:
        """Answer a command the server waits for (request id 0: nobody waits)."""
        if request_id:
            self.outbox.put(CommandResult(request_id, not refused, refused, run_token))

    def on_set_controller(self, cmd: SetController) -> None:
        """Switch controller: a new run. A specification that does not validate or
        build is refused, and the controller it was meant to replace stops too: no
        locks until the experimenter sends one that does (safety over continuity)."""
        try:
            new = build(cmd.spec)
        except Exception as exc:
            self._not_started(cmd, f"controller {cmd.spec.name!r} rejected: {exc}; "
                                   f"running {_resting()!r}")
            return
        wrong_device = "" if _is_resting(cmd.spec.name) or cmd.device is None \
            else cmd.device.refusal(self.device.identity)
        if wrong_device:
            # The layout is not this device's, as for a spec that does not build.
            self._not_started(cmd, f"controller {cmd.spec.name!r} not started: "
                                   f"{wrong_device}")
            return
        if cmd.wearer is not None:
            try:
                device, config = self._new_device(cmd.wearer)
            except Exception as exc:
                self._not_started(cmd, f"simulation seed {cmd.wearer.seed}, script "
                                       f"{cmd.wearer.script!r} rejected: {exc}; running "
                                       f"{_resting()!r}")
                return
            self._put_on(device, config, new)
        token = self._run(new, cmd.spec, self._target(cmd.spec, cmd.max_ticks),
                          cmd.max_ticks, cmd.device)
        self.answer(cmd.request_id, "", token)

    def _not_started(self, cmd: SetController, refused: str) -> None:
        """The controller asked for does not start, and the one it was to replace stops
        too (released, a new run of `none`): shown to the experimenter and answered."""
        self.outbox.put(WorkerError(refused))
        self.answer(cmd.request_id, refused,
                    0 if self.state is State.IDLE else self._fall_back())

    def _wearer(self) -> Wearer | None:
        """The in-process simulator's wearer now, at the speed asked for it (None for
        any other device)."""
        c = self.config
        if c.device_kind != "sim":
            return None
        return Wearer(c.device_seed, c.device_script, c.device_speed)

    def _new_device(self, wearer: Wearer) -> tuple[Device, WorkerConfig]:
        """The in-process simulator of `wearer`, not yet open, and the configuration it
        makes the worker's. Raises whatever makes it fail (an unknown script)."""
        config = replace(self.config, device_seed=wearer.seed, device_script=wearer.script,
                         device_speed=wearer.speed or self.config.device_speed)
        return make_device(config, self.parent.server_pid), config

    def _put_on(self, device: Device, config: WorkerConfig, controller: Controller) -> None:
        """The old device lets go before the new one opens (a failure to open ends the
        worker, released); a calibration being collected is abandoned. `controller` runs
        on the new wearer with fresh timing: health counts ticks from its first sample,
        reported at once."""
        self.abandon("the simulated wearer changed")
        back = self.state
        self.go(State.RELEASING)
        self.device.close()
        self.device = device
        self.device.open()
        self.config = config
        self.go(back)
        self.loop = self._new_loop(controller)
        self.next_status = 0.0

    def on_set_simulation(self, cmd: SetSimulation) -> None:
        """Another simulated wearer: the old device lets go before the new one opens (a
        failure to open ends the worker, released), with a fresh controller of the same
        specification, as a new run."""
        spec = self.spec
        recalibrate = (cmd.seed != self.config.device_seed
                       and spec.settings.calibration is not None)
        if recalibrate:
            # A calibration is per donning: another virtual participant's standing
            # angles are not the ones it measured. Uncalibrated, the E-UMC never locks.
            spec = replace(spec, settings=replace(spec.settings, calibration=None))
        try:
            new_device, sim_config = self._new_device(Wearer(cmd.seed, cmd.script, cmd.speed))
            fresh = build(spec)
        except Exception as exc:
            self.refuse(cmd, f"simulation seed {cmd.seed}, script {cmd.script!r} "
                             f"rejected: {exc}")
            return
        self._put_on(new_device, sim_config, fresh)
        self.spec = spec
        if recalibrate:
            self.outbox.put(WorkerError(
                f"controller {spec.name!r}: its calibration was made on another wearer; "
                "it runs uncalibrated (no locks) until calibrated again"))
        self.answer(cmd.request_id, "", self.runs.start(self.spec, self.device.kind,
                                                        cmd.max_ticks))

    def on_calibrate(self, cmd: Calibrate) -> None:
        """Collect the next seconds of samples beside the running controller: a job,
        not a state (the worker stays idle or controlling; `after_tick` feeds it)."""
        self.calibration = CalibrationJob(cmd, self.config)

    def on_bringup(self, cmd: BringupCommand) -> None:
        """The step owns the device for its few seconds (the loop pauses; the step
        answers samples itself) and always releases after it."""
        self.abandon("a hardware bring-up step ran")
        self.go(State.BRINGUP)
        self.outbox.put(bringup.handle(cmd, self.device))
        self.leave_for(State.IDLE)
        self.loop = self._new_loop(self.loop.controller)  # fresh timing after it

    def on_stop(self, _cmd: StopWorker) -> None:
        """Release and leave the loop."""
        self.stopping.set()

    def abandon(self, why: str) -> None:
        """A calibration cut short still gets its answer, with the reason."""
        job = self.calibration
        if job is not None:
            self.outbox.put(CalibrationResult(job.cmd.request_id, False,
                                              f"calibration abandoned: {why}",
                                              samples=len(job.q)))
            self.calibration = None

    # -- the loop ------------------------------------------------------------------------

    def receive(self) -> None:
        """Every command waiting on the pipe, at normal scheduling (building a controller
        is no real-time work)."""
        loop_scheduling(False)
        while self.cmd_conn.poll():
            try:
                cmd = self.cmd_conn.recv()
            except (EOFError, OSError):
                self.stopping.set()
                break
            self.dispatch(cmd)
            if self.stopping.is_set():
                break
        loop_scheduling(paced(self.config))

    def after_tick(self, record: TickRecord) -> None:
        """Hand the record to the server; end a timed run; feed a calibration."""
        self.outbox.put_record(record)
        runs = self.runs
        runs.ticks += 1
        if runs.limit is not None and runs.ticks >= runs.limit:
            self._back_to_real_time()  # first: the next run is announced at real time
            if self.state is State.TRIAL:
                # A timed run is over: back to no controller (no locks), a new run.
                self._fall_back()
            else:
                # A timed run of a new simulated wearer (a recording): the data ends,
                # the controller goes on, in a run of its own.
                runs.start(self.spec, self.device.kind)
        job = self.calibration
        if job is not None and job.add(record):
            self.finish_calibration(job)

    def _back_to_real_time(self) -> None:
        """A timed run is over: a sped-up simulated wearer goes on at real time. What it
        did faster than real time after the run was stored and never read (a third of
        a virtual study's ticks, and of its time). The speed asked for stays the
        configuration's: the next wearer put on without one runs at it."""
        set_speed = getattr(self.device, "set_speed", None)  # the in-process simulator
        if set_speed is None or float(getattr(self.device, "speed", 1.0)) <= 1.0:
            return
        set_speed(1.0)

    def finish_calibration(self, job: CalibrationJob) -> None:
        """Answer the calibration; a running E-UMC takes its offsets at once, as a new
        run (its sample count carries over)."""
        result, offsets = job.finish(self.spec)
        self.outbox.put(result)
        self.calibration = None
        if offsets is None:
            return
        try:
            spec = replace(self.spec, settings=replace(self.spec.settings,
                                                       calibration=offsets))
            new = build(spec)
        except Exception as exc:
            self.outbox.put(WorkerError(f"applying the calibration failed: {exc}"))
            return
        self.loop.controller, self.spec = new, spec
        self.runs.start(spec, self.device.kind, count_again=False)

    def run(self) -> None:
        """The 100 Hz loop, until asked to stop or the server is gone."""
        # Everything allocated so far lives for the whole run: keep the collector from
        # scanning it on every cycle (fewer, shorter pauses inside ticks).
        gc.collect()
        gc.freeze()
        held = False  # a sped-up simulation waiting for the server (see `hold`)
        silent = False  # no sample within the last read's timeout (see below)
        outbox, stopping = self.outbox, self.stopping
        command_waiting = _poller(self.cmd_conn)
        loop_scheduling(paced(self.config))
        now = next_watch = time.monotonic()
        while not stopping.is_set():
            if now >= next_watch:
                # At most once a sample period: a real-time loop looks at every tick as
                # before, a sped-up simulation does not spend a system call per tick.
                next_watch = now + PARENT_CHECK_S
                gone = self.parent.gone()
            else:
                gone = False
            if gone or outbox.broken.is_set():
                self.exit_code = 4  # the server is gone: release and leave
                break
            if command_waiting():
                self.receive()
                if stopping.is_set():
                    break
            device = self.device
            held = hold(device, outbox, held)
            record = None if held else self.loop.tick(timeout=0.05)
            if record is None and not held and not silent and device.kind == "udp":
                # 50 ms (5 samples) without a sample: send the release now instead of
                # leaving a held lock to the device's 100 ms watchdog; a device that
                # stopped talking may still be listening. Once per silence.
                device.release()
            silent = record is None and not held
            if record is not None:
                self.after_tick(record)
                if self.gate is not None:
                    self.check_device()
            now = time.monotonic()
            if now >= self.next_status:
                self.next_status = now + self.config.status_interval
                outbox.put(status(self.loop, outbox, self.pid, self.runs.token,
                                  device.kind, device.faults(), self.state))

    def check_device(self) -> None:
        """Stop a controller, released, when the device on the link is no longer the
        one its encoder layout belongs to (swapped, or rebooted as another device). Its
        lock on that device's first sample was already withheld (`_new_loop`)."""
        why = self._gate_refusal()
        if why:
            name = self.spec.name
            self.outbox.put(WorkerError(f"controller {name!r} stopped, released: {why}"))
            self._fall_back()

    def stop(self) -> None:
        """Every way out of the loop: through RELEASING to STOPPING, then `let_go`."""
        self.calibration = None
        if self.state is not State.STOPPING:
            self.leave_for(State.STOPPING)
        let_go(self.device)


def _poller(conn: Connection) -> Callable[[], bool]:
    """`conn.poll()` (a command or the end of the pipe waiting?) for every tick of the
    loop: `Connection.poll` builds and closes a selector per call, about 10 us, as much
    as a simulated tick's controller; a `select.poll` registered once asks the kernel
    alone. A hang-up or error counts as waiting, as it does for `Connection.poll`, so
    `receive` meets the end of the pipe as before."""
    if not hasattr(select, "poll"):
        return conn.poll
    poll = select.poll()
    poll.register(conn.fileno(), select.POLLIN)
    return lambda: bool(poll.poll(0))


def hold(device: Device, outbox: Outbox, held: bool) -> bool:
    """Whether a sped-up simulated device should wait for the server to catch up.

    Only a simulation faster than real time waits (its device time is virtual, so
    waiting changes nothing in the data); it restarts its clock when it resumes, so
    the samples it skipped are not delivered in one burst.
    """
    # Duck-typed: a UDP worker does not import the simulator for this.
    resync = getattr(device, "resync", None)
    if resync is None or float(getattr(device, "speed", 1.0)) <= 1.0:
        return False
    if outbox.backlog() > (BACKLOG_RESUME if held else BACKLOG_HOLD):
        time.sleep(0.002)
        return True
    if held:
        resync()
    return False


class CalibrationJob:
    """Collects raw hip angles of the next `seconds` of ticks, then calibrates."""

    def __init__(self, cmd: Calibrate, worker: WorkerConfig) -> None:
        self.cmd = cmd
        self.worker = worker
        self.needed = max(10, round(cmd.seconds / SAMPLE_PERIOD_S))
        self.q: list[tuple[float, float]] = []

    def add(self, r: TickRecord) -> bool:
        """Take one tick; True when enough have been collected."""
        self.q.append((r.q_raw_left, r.q_raw_right))
        return len(self.q) >= self.needed

    def finish(self, running: ControllerSpec
               ) -> tuple[CalibrationResult, tuple[float, float] | None]:
        """The result, and the offsets a running E-UMC takes at once (None otherwise)."""
        rid = self.cmd.request_id
        q = np.asarray(self.q, dtype=np.float64)
        try:
            # The running controller's models, else the worker's default model set.
            spec = running
            if spec.models is None and not spec.models_path:
                spec = ControllerSpec(_resting(), models_path=self.worker.models_path)
            mset = load_models(spec)
            start = mset.start_posture()
            cal = calibrate(q, start, max_std=math.radians(self.cmd.max_std_deg))
        except (CalibrationError, ValueError) as exc:
            std = np.nanstd(q, axis=0) if q.size else np.array([math.nan, math.nan])
            return CalibrationResult(rid, False, str(exc), std_left_deg=math.degrees(std[0]),
                                     std_right_deg=math.degrees(std[1]), samples=len(q)), None
        std = q.std(axis=0)
        result = CalibrationResult(
            rid, True, "calibrated", cal.offset_left, cal.offset_right,
            math.degrees(std[0]), math.degrees(std[1]), len(q),
        )
        return result, ((cal.offset_left, cal.offset_right)
                        if needs_calibration(running.name) else None)


def status(
    loop: ControlLoop, outbox: Outbox, pid: int, run_token: int, kind: str, faults: list[str],
    state: State,
) -> WorkerStatus:
    """The heartbeat the server shows as health."""
    last = loop.last_sample_at
    age = time.monotonic() - last if last is not None else math.inf
    return WorkerStatus(
        pid=pid,
        run_token=run_token,
        device_kind=kind,
        loop=LoopReport(controller=loop.controller.name, dropped_records=outbox.dropped,
                        **dataclasses.asdict(loop.timing.summary())),
        device=DeviceReport(alive=age < 0.5, last_sample_age_s=age, faults=faults,
                            implausible_samples=loop.implausible,
                            link_drops=loop.device.link_counters()),
        state=state.value,
        identity=loop.device.identity,
    )
