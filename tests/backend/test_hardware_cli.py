"""`exostudy hardware` against a running server (real HTTP, the worker and the UDP device
simulator as processes): it logs in, runs steps, and reports refusals with the reason."""

from __future__ import annotations

import json

import pytest

from backend.core.config import Settings
from backend.hardware_cli import main
from tests.live_server import running_server
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow


def test_steps_from_the_command_line(settings: Settings, experimenter: dict[str, str],
                                     monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{free_udp_port()}", "device_script": "standing"})
    monkeypatch.delenv("EXOSTUDY_TOKEN", raising=False)
    with running_server(settings) as url:
        base = ["--url", url, "--user", experimenter["username"]]
        monkeypatch.setenv("EXOSTUDY_PASSWORD", "wrong password")
        assert main([*base, "status"]) == 2
        assert "refused: 401" in capsys.readouterr().err

        monkeypatch.setenv("EXOSTUDY_PASSWORD", experimenter["password"])

        def streaming() -> bool:
            main([*base, "--json", "link"])
            out = json.loads(capsys.readouterr().out)
            return bool(out["result"]["passed"])

        wait_for(streaming, 60, "the device to stream")
        assert main([*base, "zero", "--seconds", "1"]) == 0
        out = capsys.readouterr().out
        assert out.startswith("zero: passed - zeroed over 100 still samples")
        assert "offsets: [" in out

        assert main([*base, "pulse", "--side", "right"]) == 2
        err = capsys.readouterr().err
        assert "refused: 422" in err and "nobody_wearing" in err

        assert main([*base, "pulse", "--side", "right", "--nobody-wearing"]) == 0
        assert "SOLENOID_RIGHT came on and went off" in capsys.readouterr().out

        assert main([*base, "--json", "status"]) == 0
        status = json.loads(capsys.readouterr().out)
        assert set(status["draft"]["steps"]) == {"link", "zero", "pulse_right"}

        # Not every step passed: the profile is stored as failed, not put in effect.
        assert main([*base, "profile"]) == 1
        out = capsys.readouterr().out
        assert "failed" in out.splitlines()[0]
        assert main([*base, "--json", "profile", "--list"]) == 0
        listed = json.loads(capsys.readouterr().out)
        assert [p["status"] for p in listed] == ["failed"]
