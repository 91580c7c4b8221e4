"""Hardware profiles (backend/study/hardware_profiles.py): which profile is in effect,
what finishing stores, what the key fingerprint and firmware version say, and the
runtime decoding with the profile's layout on hardware only."""

from __future__ import annotations

import asyncio
import hashlib
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from backend.core.config import Settings
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.db.hardware import HardwareProfile
from backend.live.runtime import Runtime
from backend.schemas.hardware import STEP_NAMES, FinishIn
from backend.study import accounts
from backend.study import hardware_profiles as hw
from controller.device.auth import load_or_create_key


def _profile(status: str, offsets: list[int], steps: dict[str, Any] | None = None
             ) -> HardwareProfile:
    return HardwareProfile(status=status, device="udp", firmware_version="fw", key_id="",
                           precompression_pct=25.0, encoder_offsets=offsets,
                           encoder_directions=[1, 1, -1, -1], cam_output_offsets=[0, 0],
                           steps=steps or {})


def _passed(names: tuple[str, ...]) -> dict[str, Any]:
    return {n: {"passed": True, "message": "", "at": "2026-01-01T00:00:00Z", "values": {}}
            for n in names}


class FakeRuntime:
    """What `finish` needs of the runtime, recording what it was asked."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.activity = asyncio.Lock()
        self.supervisor = SimpleNamespace(config=SimpleNamespace(controller="none"))
        self.loaded = 0
        self.idled = 0

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
        # The in-process simulator's version is known; the typed one is for hardware.
        assert done.firmware_version.startswith("in-process simulator")
        assert (rt.loaded, rt.idled) == (1, 1)
    engine.dispose()


def test_key_id_is_a_fingerprint_and_firmware_version_is_typed_for_hardware(
        tmp_path: Path, settings: Settings) -> None:
    key_file = tmp_path / "device.key"
    key = load_or_create_key(key_file)
    hardware: Any = SimpleNamespace(settings=settings.model_copy(update={
        "device_kind": "udp", "device_spawn_simulator": False, "device_key_file": key_file}))
    assert hw.key_id(hardware) == hashlib.sha256(key).hexdigest()[:8]
    assert hw.key_id(hardware) != key.hex()[:8]  # a digest, not the key's first digits
    assert hw.device_label(hardware) == "udp"
    assert hw.firmware_version(hardware, " exo-fw 1.2 ") == "exo-fw 1.2"
    assert hw.firmware_version(hardware, None) == "not reported (protocol 2)"
    sim: Any = SimpleNamespace(settings=settings)  # device_kind "sim"
    assert hw.key_id(sim) == "" and hw.device_label(sim) == "sim"


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
    cfg = hardware.controller_spec("none").settings
    assert cfg.encoder_offsets == (100, 200, 300, 400)
    assert cfg.encoder_directions == (1, 1, -1, -1)
    simulated = Runtime(settings.model_copy(update={
        "device_kind": "udp", "device_spawn_simulator": True}), engine)
    simulated.load_hardware_layout()
    assert simulated.encoder_layout is None
    assert simulated.controller_spec("none").settings.encoder_offsets == (3100, 3100, 12900,
                                                                         12900)
    engine.dispose()
