"""The worker's state machine (`backend.worker.machine`), transition by transition.

Most tests drive the machine in this process on the simulated device, sample by sample,
so every transition and every refusal is checked exactly; the last ones run the real
worker process through its pipe, as the server does.
"""

from __future__ import annotations

import collections
import multiprocessing as mp
import os
import threading
import typing
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest

from backend.worker.child_processes import ParentWatch
from backend.worker.devices import make_device
from backend.worker.machine import (
    EDGES,
    KINDS,
    LOCKING,
    REFUSALS,
    RULES,
    WHILE_CALIBRATING,
    Machine,
    State,
    TransitionError,
    kind_of,
)
from backend.worker.messages import (
    BringupCapture,
    BringupCommand,
    BringupPulse,
    BringupRelease,
    BringupResult,
    BringupWatchdog,
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
)
from backend.worker.outbox import Outbox
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor
from controller.controllers.spec import ControllerSpec
from controller.lowlevel.encoders import DEFAULT_LAYOUT
from controller.stop_flag import SignalSafeFlag
from tests.backend.worker.unchecked import unchecked_spec
from tests.polling import wait_for

ID, C, T, B, R, S = (State.IDLE, State.CONTROLLING, State.TRIAL, State.BRINGUP,
                    State.RELEASING, State.STOPPING)
#: Not a state: controlling with a calibration being collected beside it (a job).
K = "calibrating"
Where = State | str


def _state(where: Where) -> State:
    """The worker's state at `where`: a calibration runs beside a controller."""
    return C if where == K else State(where)
PEC = ControllerSpec("pec")
NONE = ControllerSpec("none")
LAY = DEFAULT_LAYOUT
#: Every command the server can send, read from the message union itself, so that a new
#: command without a rule in every state fails here.
COMMAND_TYPES = typing.get_args(WorkerCommand)


# -- the tables ---------------------------------------------------------------------------

def test_every_way_out_of_a_locking_state_to_a_safe_one_passes_through_releasing() -> None:
    safe = set(State) - LOCKING - {R}
    assert safe == {ID, S}
    assert not [(a, b) for a, b in EDGES if a in LOCKING and b in safe]
    # Stopping is reached from releasing only, whatever the state before.
    assert [a for a, b in EDGES if b is S] == [R]
    assert all((a, R) in EDGES for a in State if a is not S and a is not R)


def test_every_command_type_has_one_kind_and_the_bringup_steps_share_one() -> None:
    assert {SetController, StopWorker, BringupRelease} <= set(COMMAND_TYPES)
    for t in COMMAND_TYPES:
        assert [k for k in KINDS if issubclass(t, k)] == [kind_of(t.__new__(t))], t
    steps = (BringupCapture, BringupPulse, BringupWatchdog, BringupRelease)
    assert {kind_of(t.__new__(t)) for t in steps} == {BringupCommand}
    assert kind_of({"name": "pec"}) is None and kind_of(None) is None
    # Every kind a sender waits on is answered in its own form when refused.
    assert set(REFUSALS) == set(KINDS) - {StopWorker}


def test_every_state_that_takes_commands_has_a_rule_for_each_and_always_takes_stop() -> None:
    assert set(RULES) == {ID, C, T}
    for state, rules in RULES.items():
        assert set(rules) == set(KINDS), state
        assert rules[StopWorker] is None, state
    # Idle takes everything (a new simulated wearer, alone or with a controller, checks
    # the device kind).
    assert [t for t, r in RULES[ID].items() if r is not None] == [SetController, SetSimulation]
    # A trial refuses every change but its stop, outright.
    assert all(isinstance(RULES[T][t], str) for t in (SetSimulation, Calibrate, BringupCommand))
    # A calibration refuses a second one and a timed trial, nothing else of its own.
    assert set(WHILE_CALIBRATING) == {Calibrate, SetController}


# -- the machine in this process ----------------------------------------------------------

class Harness:
    """A machine on the simulated device (fast), whose answers and device releases are
    recorded; ticks are driven one sample at a time."""

    def __init__(self, **config: Any) -> None:
        self.config = WorkerConfig(device_kind="sim", device_speed=50,
                                   device_script="squat-sequence", **config)
        device = make_device(self.config, os.getppid())
        device.open()
        self.releases = 0
        self._conn_a, self._conn_b = mp.Pipe(duplex=False)
        self.outbox = Outbox(self._conn_b)  # its sender thread is never started
        self.stopping = SignalSafeFlag()
        self.m = Machine(self.config, device, self.outbox, self._conn_a, ParentWatch(os.getppid()),
                         self.stopping)
        self._spy(device)

    def _spy(self, device: Any) -> None:
        release = device.release

        def counting() -> None:
            self.releases += 1
            release()

        device.release = counting

    def messages(self) -> list[Any]:
        taken = [m for m in self.outbox.messages if not isinstance(m, tuple)]
        self.outbox.messages.clear()
        self.outbox.records = []
        return taken

    def send(self, cmd: Any) -> list[Any]:
        device = self.m.device
        self.m.dispatch(cmd)
        if self.m.device is not device:
            self._spy(self.m.device)
        return self.messages()

    def ticks(self, n: int) -> None:
        for _ in range(n):
            record = self.m.loop.tick(timeout=2.0)
            assert record is not None
            self.m.after_tick(record)

    def trace_since(self, mark: int) -> list[State]:
        return self.m.trace[mark:]

    def close(self) -> None:
        self.m.stop()
        self._conn_a.close()
        self._conn_b.close()


@pytest.fixture
def h() -> Iterator[Harness]:
    harness = Harness()
    harness.messages()
    try:
        yield harness
    finally:
        harness.close()


def _runs(msgs: list[Any]) -> list[str]:
    return [m.controller for m in msgs if isinstance(m, RunStarted)]


def _answer(msgs: list[Any], kind: type) -> Any:
    (answer,) = [m for m in msgs if isinstance(m, kind)]
    return answer


def _into(h: Harness, state: Where) -> None:
    """Bring the machine from idle into `state` through its commands."""
    if state is C:
        h.send(SetController(PEC, request_id=90))
    elif state is T:
        h.send(SetController(PEC, max_ticks=10_000, request_id=91))
    elif state == K:
        h.send(SetController(PEC, request_id=92))
        h.send(Calibrate(seconds=30.0, request_id=93))
        assert h.m.calibration is not None
    assert h.m.state is _state(state)


def test_idle_to_controlling_and_back_through_releasing(h: Harness) -> None:
    mark = len(h.m.trace)
    msgs = h.send(SetController(PEC, request_id=1))
    assert _runs(msgs) == ["pec"] and _answer(msgs, CommandResult).ok
    assert h.trace_since(mark) == [C] and h.releases == 0
    h.ticks(20)
    msgs = h.send(SetController(NONE, request_id=2))
    assert _runs(msgs) == ["none"] and _answer(msgs, CommandResult).ok
    assert h.trace_since(mark) == [C, R, ID] and h.releases == 1


def test_controlling_hands_over_to_another_controller_or_a_trial_directly(h: Harness) -> None:
    _into(h, C)
    mark = len(h.m.trace)
    assert _runs(h.send(SetController(PEC, request_id=3))) == ["pec"]
    assert h.m.state is C
    msgs = h.send(SetController(PEC, max_ticks=30, request_id=4))
    assert _runs(msgs) == ["pec"] and _answer(msgs, CommandResult).ok
    assert h.trace_since(mark) == [T] and h.releases == 0


def test_a_timed_trial_ends_by_itself_through_releasing_to_none(h: Harness) -> None:
    mark = len(h.m.trace)
    h.send(SetController(PEC, max_ticks=40, request_id=5))
    h.ticks(39)
    assert h.m.state is T and _runs(h.messages()) == []
    h.ticks(1)
    (run,) = [m for m in h.messages() if isinstance(m, RunStarted)]
    # The next run says the trial's ended by its time (its data is whole); a stop from
    # the server ends one without saying so.
    assert (run.controller, run.limit_reached) == ("none", 40)
    assert h.trace_since(mark) == [T, R, ID] and h.releases == 1
    assert h.m.loop.controller.name == "none"
    # The sped-up wearer goes on at real time: no ticks faster than anyone asked for.
    # The speed asked for stays (the next wearer put on without one takes it).
    assert h.m.device.speed == 1.0 and h.m.config.device_speed == 50  # type: ignore[attr-defined]


def test_a_timed_recording_of_a_new_wearer_ends_the_speed_up_too(h: Harness) -> None:
    msgs = h.send(SetSimulation(seed=5, script="walking", speed=50, request_id=16,
                                max_ticks=20))
    assert _answer(msgs, CommandResult).ok
    h.ticks(19)
    assert h.m.device.speed == 50  # type: ignore[attr-defined]
    h.ticks(1)
    msgs = h.messages()
    assert _runs(msgs) == ["none"] and h.m.state is ID
    assert h.m.device.speed == 1.0  # type: ignore[attr-defined]
    (run,) = [m for m in msgs if isinstance(m, RunStarted)]
    assert run.wearer == Wearer(5, "walking", 50)  # what the server records


def test_a_trial_with_its_wearer_starts_at_the_wearers_first_sample(h: Harness) -> None:
    _into(h, C)
    h.ticks(30)  # the old wearer is 0.3 s into its script
    mark = len(h.m.trace)
    msgs = h.send(SetController(PEC, max_ticks=40, request_id=17,
                                wearer=Wearer(7, "walking", 40.0)))
    assert _answer(msgs, CommandResult).ok and _runs(msgs) == ["pec"]
    # Released and closed (which releases once more) before the new wearer opens.
    assert h.trace_since(mark) == [R, C, T] and h.releases == 2
    assert (h.m.config.device_seed, h.m.config.device_script) == (7, "walking")
    assert h.m.device.speed == 40.0  # type: ignore[attr-defined]
    record = h.m.loop.tick(timeout=2.0)
    assert record is not None and record.t == 0.0 and record.seq == 0
    h.m.after_tick(record)
    h.ticks(39)
    assert _runs(h.messages()) == ["none"] and h.m.state is ID
    assert h.m.device.speed == 1.0  # type: ignore[attr-defined]


def test_a_trial_whose_wearer_cannot_be_made_stops_the_controller_it_replaces(
        h: Harness) -> None:
    _into(h, C)
    mark = len(h.m.trace)
    msgs = h.send(SetController(PEC, max_ticks=40, request_id=18,
                                wearer=Wearer(7, "cartwheels", 40.0)))
    answer = _answer(msgs, CommandResult)
    assert not answer.ok and "cartwheels" in answer.message
    assert _runs(msgs) == ["none"] and h.trace_since(mark) == [R, ID]
    assert h.m.config.device_script == "squat-sequence"  # the wearer on the device stays


def test_a_trial_is_stopped_only_by_none(h: Harness) -> None:
    _into(h, T)
    mark = len(h.m.trace)
    msgs = h.send(SetController(NONE, request_id=6))
    assert _runs(msgs) == ["none"] and _answer(msgs, CommandResult).ok
    assert [m.limit_reached for m in msgs if isinstance(m, RunStarted)] == [None]
    assert h.trace_since(mark) == [R, ID] and h.releases == 1


@pytest.mark.parametrize("base", [ID, C])
def test_a_calibration_is_collected_beside_the_state_it_started_in(h: Harness,
                                                                   base: State) -> None:
    _into(h, base)
    mark, token = len(h.m.trace), h.m.runs.token
    h.send(Calibrate(seconds=0.2, max_std_deg=90.0, request_id=7))
    assert h.m.state is base and h.m.calibration is not None
    h.ticks(19)
    assert h.m.state is base and not h.messages()
    h.ticks(1)
    msgs = h.messages()
    result = _answer(msgs, CalibrationResult)
    assert result.request_id == 7 and result.samples == 20
    # No transition and no release at all: the controller ran on untouched (pec takes
    # no offsets, so no new run either).
    assert h.m.calibration is None and h.trace_since(mark) == [] and h.releases == 0
    assert h.m.state is base and h.m.runs.token == token and _runs(msgs) == []


def test_a_controller_change_while_calibrating_keeps_the_calibration(h: Harness) -> None:
    _into(h, K)
    mark = len(h.m.trace)
    msgs = h.send(SetController(NONE, request_id=8))
    assert _runs(msgs) == ["none"] and h.m.state is ID and h.m.calibration is not None
    assert not [m for m in msgs if isinstance(m, CalibrationResult)]
    # Controlling to idle is released at once, calibration or not.
    assert h.trace_since(mark) == [R, ID] and h.releases == 1
    h.ticks(5)
    assert len(h.m.calibration.q) == 5


def test_a_rejected_controller_while_calibrating_beside_idle_starts_no_run(h: Harness) -> None:
    h.send(Calibrate(seconds=30.0, request_id=16))
    msgs = h.send(SetController(unchecked_spec("umc"), request_id=17))
    answer = _answer(msgs, CommandResult)
    assert not answer.ok and answer.run_token == 0 and _runs(msgs) == []
    assert h.m.state is ID and h.m.calibration is not None and h.releases == 0


def test_a_new_wearer_abandons_a_calibration_and_keeps_the_controller(h: Harness) -> None:
    _into(h, K)
    mark = len(h.m.trace)
    msgs = h.send(SetSimulation(seed=4, script="walking", request_id=9))
    cal = _answer(msgs, CalibrationResult)
    assert not cal.ok and "abandoned" in cal.message and "simulated wearer" in cal.message
    assert _answer(msgs, CommandResult).ok and _runs(msgs) == ["pec"]
    # Released, then closed (which releases once more) before the new device opens.
    assert h.trace_since(mark) == [R, C] and h.releases == 2
    assert h.m.calibration is None
    assert h.m.config.device_seed == 4


def test_a_new_wearer_from_idle_passes_through_releasing(h: Harness) -> None:
    mark = len(h.m.trace)
    msgs = h.send(SetSimulation(seed=5, script="walking", request_id=10))
    assert _answer(msgs, CommandResult).ok and _runs(msgs) == ["none"]
    assert h.trace_since(mark) == [R, ID] and h.releases == 2


def test_a_bringup_step_runs_from_idle_and_leaves_through_releasing(h: Harness) -> None:
    mark = len(h.m.trace)
    msgs = h.send(BringupCapture(seconds=0.1, request_id=11))
    result = _answer(msgs, BringupResult)
    assert result.ok and not result.refused and len(result.samples) == 10
    assert h.trace_since(mark) == [B, R, ID] and h.releases >= 1


def test_a_bringup_step_abandons_a_calibration_collected_while_idle(h: Harness) -> None:
    h.send(Calibrate(seconds=30.0, request_id=12))
    mark = len(h.m.trace)
    msgs = h.send(BringupCapture(seconds=0.1, request_id=13))
    assert "bring-up" in _answer(msgs, CalibrationResult).message
    assert _answer(msgs, BringupResult).ok
    assert h.trace_since(mark) == [B, R, ID] and h.m.calibration is None


def test_a_rejected_controller_falls_back_to_none_through_releasing(h: Harness) -> None:
    _into(h, C)
    mark = len(h.m.trace)
    msgs = h.send(SetController(unchecked_spec("umc"), request_id=14))
    answer = _answer(msgs, CommandResult)
    assert not answer.ok and "umc" in answer.message and "models" in answer.message
    assert _runs(msgs) == ["none"] and answer.run_token == h.m.runs.token
    assert h.trace_since(mark) == [R, ID] and h.releases == 1


def test_a_rejected_controller_in_idle_starts_no_run(h: Harness) -> None:
    nan = {"settings": {"velocity_threshold": float("nan")}}
    msgs = h.send(SetController(unchecked_spec("pec", nan), request_id=15))
    answer = _answer(msgs, CommandResult)
    assert not answer.ok and "velocity_threshold" in answer.message
    assert answer.run_token == 0 and _runs(msgs) == [] and h.m.state is ID


#: (state, command, words of the reason): every command each state refuses.
REFUSED: list[tuple[Where, Any, str]] = [
    (C, BringupCapture(seconds=0.1, request_id=20), "'pec' is running"),
    (C, BringupPulse("left", 0.1, LAY.offsets, LAY.directions, 2.0, request_id=21),
     "'pec' is running"),
    (C, BringupWatchdog("left", LAY.offsets, LAY.directions, 2.0, request_id=22),
     "'pec' is running"),
    (T, SetController(PEC, request_id=23), "timed trial"),
    (T, SetController(NONE, max_ticks=5, request_id=24), "timed trial"),
    (T, SetSimulation(seed=2, script="walking", request_id=25), "simulated wearer"),
    (T, SetController(NONE, request_id=35, wearer=Wearer(2, "walking")), "timed trial"),
    (T, Calibrate(request_id=26), "timed trial"),
    (T, BringupCapture(seconds=0.1, request_id=27), "timed trial"),
    (T, BringupPulse("left", 0.1, LAY.offsets, LAY.directions, 2.0, request_id=28),
     "timed trial"),
    (T, BringupWatchdog("left", LAY.offsets, LAY.directions, 2.0, request_id=29),
     "timed trial"),
    (K, Calibrate(request_id=30), "already being collected"),
    (K, SetController(PEC, max_ticks=5, request_id=31), "calibration"),
    (K, BringupCapture(seconds=0.1, request_id=32), "'pec' is running"),
    (K, BringupPulse("left", 0.1, LAY.offsets, LAY.directions, 2.0, request_id=33),
     "'pec' is running"),
    (K, BringupWatchdog("left", LAY.offsets, LAY.directions, 2.0, request_id=34),
     "'pec' is running"),
]


@pytest.mark.parametrize(("state", "cmd", "words"), REFUSED,
                         ids=[f"{getattr(s, 'value', s)}-{type(c).__name__}-{c.request_id}"
                              for s, c, _ in REFUSED])
def test_each_refused_command_is_answered_with_its_reason(h: Harness, state: Where, cmd: Any,
                                                          words: str) -> None:
    _into(h, state)
    mark, token, releases = len(h.m.trace), h.m.runs.token, h.releases
    msgs = h.send(cmd)
    if isinstance(cmd, Calibrate):
        answer = _answer(msgs, CalibrationResult)
    elif isinstance(cmd, SetController | SetSimulation):
        answer = _answer(msgs, CommandResult)
        assert answer.run_token == 0
        assert [m.message for m in msgs if isinstance(m, WorkerError)] == [answer.message]
    else:
        answer = _answer(msgs, BringupResult)
        assert answer.refused and answer.samples == ()
    assert answer.request_id == cmd.request_id and not answer.ok
    assert words in answer.message
    # Nothing changed: same state, same run, the device untouched.
    assert h.trace_since(mark) == [] and h.m.state is _state(state)
    assert (h.m.calibration is not None) == (state == K)
    assert h.m.runs.token == token and h.releases == releases and _runs(msgs) == []


@pytest.mark.parametrize("cmd", [
    SetSimulation(seed=2, script="walking", request_id=40),
    SetController(PEC, max_ticks=40, request_id=41, wearer=Wearer(2, "walking"))],
    ids=["simulation", "controller-with-wearer"])
def test_a_simulation_change_is_refused_without_the_simulator(h: Harness, cmd: Any) -> None:
    h.m.config = replace(h.m.config, device_kind="udp")  # what the rule looks at
    msgs = h.send(cmd)
    answer = _answer(msgs, CommandResult)
    assert not answer.ok and "not the in-process simulator" in answer.message
    assert h.m.state is ID and _runs(msgs) == []


@pytest.mark.parametrize("state", [ID, C, T, K])
def test_stopping_passes_through_releasing_from_every_state(state: Where) -> None:
    h = Harness()
    try:
        _into(h, state)
        h.ticks(5)
        h.send(StopWorker())
        assert h.stopping.is_set()  # the loop ends; its way out is `stop`
        mark, releases = len(h.m.trace), h.releases
        h.m.stop()
        assert h.trace_since(mark) == [R, S]
        assert h.releases >= releases + 1
    finally:
        h._conn_a.close()
        h._conn_b.close()


def test_something_that_is_not_a_command_is_reported_and_changes_nothing(h: Harness) -> None:
    _into(h, C)
    mark, token = len(h.m.trace), h.m.runs.token
    msgs = h.send({"name": "pec"})  # a mapping is not a command (nor a specification)
    assert [m.message for m in msgs] == ["the worker is controlling: it takes no dict"]
    assert h.trace_since(mark) == [] and h.m.runs.token == token


def test_a_transition_missing_from_the_table_is_an_error(h: Harness) -> None:
    _into(h, T)
    with pytest.raises(TransitionError, match="trial to idle"):
        h.m.go(ID)
    assert h.m.state is T


def test_the_worker_starts_in_the_state_of_its_configured_controller() -> None:
    h = Harness(spec=PEC)
    try:
        assert h.m.state is C and h.m.trace == [ID, C] and _runs(h.messages()) == ["pec"]
    finally:
        h.close()
    h = Harness(spec=unchecked_spec("umc"))  # does not build: none, idle
    try:
        msgs = h.messages()
        assert h.m.state is ID and _runs(msgs) == ["none"]
        assert any("umc" in m.message for m in msgs if isinstance(m, WorkerError))
    finally:
        h.close()


# -- the real worker process --------------------------------------------------------------

class Answers:
    """What the real worker sends back, by request id."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.results: dict[int, Any] = {}
        self.runs: list[RunStarted] = []
        self.by_kind: collections.Counter[str] = collections.Counter()

    def _put(self, answer: Any) -> None:
        with self.lock:
            self.results[answer.request_id] = answer

    def callbacks(self) -> WorkerCallbacks:
        return WorkerCallbacks(on_run_started=self.runs.append,
                               on_command_result=self._put, on_calibration=self._put,
                               on_bringup=self._put)

    def wait(self, rid: int) -> Any:
        wait_for(lambda: rid in self.results, 60, f"the answer to request {rid}")
        return self.results[rid]


def test_the_real_worker_refuses_what_a_running_trial_does_not_take() -> None:
    got = Answers()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim", device_speed=5,
                                        device_script="squat-sequence", status_interval=0.1),
                           got.callbacks())
    sup.start()
    try:
        def state() -> str:
            st = sup.state.status
            return st.state if st is not None else ""

        wait_for(lambda: state() == "idle", 60, "the idle worker")
        trial = got.wait(sup.set_controller(PEC, max_ticks=100_000))
        assert trial.ok
        wait_for(lambda: state() == "trial", 30, "the trial state")

        rid = sup.set_controller(ControllerSpec("pec"))
        assert not got.wait(rid).ok and "timed trial" in got.results[rid].message
        srid = sup.set_simulation(2, "walking")
        assert srid is not None
        assert not got.wait(srid).ok and "simulated wearer" in got.results[srid].message
        crid = sup.request_calibration(1.0, 1.0)
        assert not got.wait(crid).ok and "timed trial" in got.results[crid].message
        brid = sup.request_bringup(BringupCapture(seconds=0.1))
        assert got.wait(brid).refused
        assert [r.controller for r in got.runs] == ["none", "pec"]  # the trial's run kept

        stop = got.wait(sup.set_controller(NONE))  # the trial's stop: taken
        assert stop.ok and got.runs[-1].controller == "none"
        wait_for(lambda: state() == "idle", 30, "idle again")
        crid = sup.request_calibration(0.2, 90.0)
        assert got.wait(crid).samples == 20  # idle takes a calibration
    finally:
        sup.stop()
    assert not sup.state.alive and sup.state.exit_code == 0


def test_the_loops_command_check_answers_as_connection_poll_does() -> None:
    """The loop asks the pipe once per tick through a registered poll (`_poller`), not
    `Connection.poll`: it must see a command, nothing, and the server's end alike."""
    from backend.worker.machine import _poller

    a, b = mp.Pipe(duplex=False)
    waiting = _poller(a)
    assert (waiting(), a.poll()) == (False, False)
    b.send(StopWorker("test"))
    assert (waiting(), a.poll()) == (True, True)
    a.recv()
    assert (waiting(), a.poll()) == (False, False)
    b.close()  # the server is gone: `receive` meets the end of the pipe
    assert (waiting(), a.poll()) == (True, True)
    with pytest.raises(EOFError):
        a.recv()
    a.close()
