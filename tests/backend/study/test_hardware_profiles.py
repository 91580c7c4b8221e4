"""Hardware profiles (backend/study/hardware_profiles.py): which profile is in effect,
what finishing stores and refuses, drafts bound to one device and expiring, the
hardware release verdict, and the runtime decoding with the profile's layout only on
the device it was made on."""

from __future__ import annotations

import asyncio
import math
from datetime import UTC, datetime, timedelta
from types import SimpleNamespace
from typing import Any

import pytest

from backend.core.config import Settings
from backend.core.errors import ConflictError
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.db.hardware import HardwareProfile
from backend.live.device_binding import BoundDevice
from backend.live.runtime import Runtime
from backend.schemas.hardware import STEP_NAMES, FinishIn
from backend.study import accounts
from backend.study import hardware_profiles as hw
from backend.worker.messages import BringupResult, WorkerStatus
from controller.device.base import DeviceIdentity

KEY_ID = "00112233aabbccdd"
ID_A = "0123456789abcdef0123456789abcdef"
ID_B = "fedcba9876543210fedcba9876543210"
DEVICE_A = BoundDevice("udp", KEY_ID, ID_A, "exo-nucleo 3")


def _profile(status: str, offsets: list[int], steps: dict[str, Any] | None = None,
             unique_id: str = ID_A, expires_at: datetime | None = None) -> HardwareProfile:
    return HardwareProfile(status=status, device="udp", firmware_version="exo-nucleo 3",
                           key_id=KEY_ID, unique_id=unique_id,
                           precompression_pct=25.0, encoder_offsets=offsets,
                           encoder_directions=[1, 1, -1, -1], cam_output_offsets=[0, 0],
                           steps=steps or {}, expires_at=expires_at)


def _passed(names: tuple[str, ...]) -> dict[str, Any]:
    return {n: {"passed": True, "message": "", "at": "2026-01-01T00:00:00Z", "values": {}}
            for n in names}


class FakeRuntime:
    """What `finish` needs of the runtime, recording what it was asked."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.activity = asyncio.Lock()
        self.supervisor = SimpleNamespace(config=SimpleNamespace(controller="none"),
                                          state=SimpleNamespace(alive=True))
        self.loaded = 0
        self.idled = 0
        self.device: BoundDevice | None = DEVICE_A

    def bound_device(self) -> BoundDevice | None:
        return self.device

    def load_hardware_layout(self) -> None:
        self.loaded += 1

    async def idle(self) -> None:
        self.idled += 1


def test_finish_completes_only_with_every_step_passed(db_url: str, settings: Settings) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        user = accounts.create_user(db, "alice", "correct horse battery staple")
        db.add(_profile("complete", [1, 2, 3, 4]))
        db.commit()
        first = hw.active_id(db)
        assert first is not None and hw.draft(db) is None
        rt: Any = FakeRuntime(settings)

        db.add(_profile("draft", [5, 6, 7, 8], _passed(STEP_NAMES[:-1])))
        db.commit()
        failed = asyncio.run(hw.finish(db, user, rt, FinishIn()))
        assert failed.status == "failed" and failed.completed_at is not None
        assert hw.active_id(db) == first  # a failed bring-up never takes effect
        assert rt.loaded == 0

        db.add(_profile("draft", [9, 10, 11, 12], _passed(STEP_NAMES)))
        db.commit()
        done = asyncio.run(hw.finish(db, user, rt, FinishIn(firmware_version="x")))
        assert done.status == "complete"
        assert hw.active_id(db) == done.id and done.id != first
        # The firmware the device reported wins over a typed one.
        assert done.firmware_version == "exo-nucleo 3"
        assert (rt.loaded, rt.idled) == (1, 1)
    engine.dispose()


def _finish_refused(db: Any, user: Any, rt: Any) -> str:
    with pytest.raises(ConflictError) as exc:
        asyncio.run(hw.finish(db, user, rt, FinishIn()))
    return str(exc.value)


def test_a_draft_of_another_device_or_past_its_lifetime_is_closed_not_finished(
        db_url: str, settings: Settings) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        user = accounts.create_user(db, "alice", "correct horse battery staple")
        rt: Any = FakeRuntime(settings)
        # A complete set of steps, measured on the simulator: refused on device A.
        db.add(_profile("draft", [1, 2, 3, 4], _passed(STEP_NAMES), unique_id=ID_B))
        db.commit()
        why = _finish_refused(db, user, rt)
        assert "no bring-up in progress" in why and "another device" in why
        assert f"made on device {ID_B}, this is device {ID_A}" in why
        assert hw.draft(db) is None and hw.active_id(db) is None
        assert db.query(HardwareProfile).one().status == "expired"
        # A draft of this device, opened more than 2 h ago: expired too.
        past = datetime.now(UTC) - timedelta(minutes=1)
        db.add(_profile("draft", [1, 2, 3, 4], _passed(STEP_NAMES), expires_at=past))
        db.commit()
        assert "expired at" in _finish_refused(db, user, rt)
        assert hw.active_id(db) is None
        # A device that has not proved its identity: nothing can be bound to it.
        rt.device = None
        assert "not proved its identity" in _finish_refused(db, user, rt)
    engine.dispose()


def test_storing_a_profile_is_refused_while_something_runs(db_url: str,
                                                          settings: Settings) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        user = accounts.create_user(db, "alice", "correct horse battery staple")
        db.add(_profile("draft", [1, 2, 3, 4], _passed(STEP_NAMES)))
        db.commit()
        rt: Any = FakeRuntime(settings)
        rt.supervisor.config.controller = "pec"
        assert "controller 'pec' is active" in _finish_refused(db, user, rt)
        assert hw.draft(db) is not None and hw.active_id(db) is None  # nothing changed
    engine.dispose()


def _release(stopped: float, off: float, back: bool = True) -> BringupResult:
    return BringupResult(1, True, "worker says", heartbeat_stopped_t=stopped,
                         drivers_off_t=off, drivers_back=back)


def test_the_hardware_release_passes_within_the_circuits_longest_hold() -> None:
    assert pytest.approx(0.040) == hw.RELEASE_LIMIT_S
    ok, msg, ms = hw.judge_release(_release(10.000, 10.040))
    assert ok and ms == pytest.approx(40.0) and "at most 40 ms" in msg
    late, msg, ms = hw.judge_release(_release(10.000, 10.050))
    assert not late and ms == pytest.approx(50.0) and "later than 40 ms" in msg
    never, msg, ms = hw.judge_release(_release(10.000, math.nan))
    assert not never and ms is None
    assert msg == ("no hardware release observed: is the heartbeat monitor fitted and its "
                   "readback wired? see docs/hardware-bringup-lab.md"
                   "#hardware-release-heartbeat")
    short, msg, _ = hw.judge_release(_release(10.000, 10.005))
    assert not short and "far shorter than 30 ms" in msg
    stuck, msg, _ = hw.judge_release(_release(10.0, 10.03, back=False))
    assert not stuck and "did not come back on" in msg
    old_fw, msg, _ = hw.judge_release(_release(math.nan, math.nan))
    assert not old_fw and msg == "worker says"


def test_firmware_version_is_the_reported_one_else_the_typed_one() -> None:
    assert hw.firmware_version(DEVICE_A, "typed") == "exo-nucleo 3"
    silent = BoundDevice("udp", KEY_ID, ID_A, "")
    assert hw.firmware_version(silent, " exo-fw 1.2 ") == "exo-fw 1.2"
    assert hw.firmware_version(silent, None) == "not reported"


def _joined(runtime: Runtime, unique_id: str, firmware: str = "exo-nucleo 3") -> None:
    """What the worker's status says once the device proved its identity."""
    runtime.supervisor.state.alive = True
    runtime.supervisor.state.status = WorkerStatus(
        pid=1, run_token=1, device_kind="udp", loop=None, device=None,  # type: ignore[arg-type]
        identity=DeviceIdentity(unique_id, firmware, KEY_ID, 5))


def test_the_runtime_decodes_with_the_profile_on_hardware_only(db_url: str,
                                                              settings: Settings) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        db.add(_profile("complete", [100, 200, 300, 400]))
        db.commit()
    hardware = Runtime(settings.model_copy(update={
        "device_kind": "udp", "device_spawn_simulator": False}), engine)
    hardware.load_hardware_layout()
    # Not before the device proved which one it is.
    assert hardware.encoder_layout is None
    assert "not proved its identity" in hardware.profile_verdict()
    _joined(hardware, ID_A)
    cfg = hardware.controller_spec("none").settings
    assert cfg.encoder_offsets == (100, 200, 300, 400)
    assert cfg.encoder_directions == (1, 1, -1, -1)
    # New firmware on the same device: still applied.
    _joined(hardware, ID_A, "exo-nucleo 4")
    assert hardware.encoder_layout is not None and hardware.profile_verdict() == ""
    # Another device on the link: refused, and the verdict names both.
    _joined(hardware, ID_B)
    assert hardware.encoder_layout is None
    verdict = hardware.profile_verdict()
    assert "refused on this device" in verdict and ID_A in verdict and ID_B in verdict
    assert "run the bring-up again" in verdict
    assert hardware.controller_spec("none").settings.encoder_offsets == (3100, 3100, 12900,
                                                                         12900)
    simulated = Runtime(settings.model_copy(update={
        "device_kind": "udp", "device_spawn_simulator": True}), engine)
    simulated.load_hardware_layout()
    assert simulated.encoder_layout is None
    assert simulated.controller_spec("none").settings.encoder_offsets == (3100, 3100, 12900,
                                                                         12900)
    engine.dispose()
