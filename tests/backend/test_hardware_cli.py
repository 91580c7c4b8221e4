"""`exostudy hardware` against a running server (real HTTP, the worker and the UDP device
simulator as processes): it logs in, runs steps, and reports refusals with the reason."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import httpx
import pytest
from sqlalchemy import select

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.models import AuthToken
from backend.hardware_cli import main
from tests.live_server import running_server
from tests.polling import free_udp_port, wait_for

ROOT = Path(__file__).resolve().parents[2]

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
            # Refused (2) until the device has joined and proved its identity.
            if main([*base, "--json", "link"]) == 2:
                assert "not proved its identity" in capsys.readouterr().err
                return False
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


def test_a_login_with_a_password_leaves_no_token_behind(
        settings: Settings, experimenter: dict[str, str], db_url: str,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Each call made a 30-day bearer token and kept it; now it revokes it at exit,
    and a token given in EXOSTUDY_TOKEN is used, not revoked."""
    monkeypatch.delenv("EXOSTUDY_TOKEN", raising=False)
    monkeypatch.setenv("EXOSTUDY_PASSWORD", experimenter["password"])
    with running_server(settings) as url:
        base = ["--url", url, "--user", experimenter["username"]]
        for _ in range(3):
            assert main([*base, "--json", "profile", "--list"]) == 0
            assert json.loads(capsys.readouterr().out) == []
        assert main([*base, "pulse", "--side", "left"]) == 2  # refused steps too
        assert "refused: 422" in capsys.readouterr().err
        assert _live_bearer_tokens(db_url) == 0
        given = httpx.post(f"{url}/api/auth/token", json=experimenter).json()
        monkeypatch.setenv("EXOSTUDY_TOKEN", given["access_token"])
        assert main([*base, "--json", "profile", "--list"]) == 0
        assert _live_bearer_tokens(db_url) == 1


def _live_bearer_tokens(db_url: str) -> int:
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        n = len(list(db.scalars(select(AuthToken).where(
            AuthToken.kind == "bearer", AuthToken.revoked_at.is_(None)))))
    engine.dispose()
    return n


@contextmanager
def _holding_steps(server: str) -> Iterator[tuple[str, threading.Event]]:
    """A front for `server` that passes logins and logouts through and holds every other
    request (a step) until the test ends: the command is then stopped mid-step. Yields
    the front's URL and an event set once a step is being held."""
    held, release = threading.Event(), threading.Event()

    class Front(BaseHTTPRequestHandler):
        def _any(self) -> None:
            length = int(self.headers.get("Content-Length") or 0)
            body = self.rfile.read(length) if length else None
            if not self.path.startswith("/api/auth/"):
                held.set()
                release.wait(60)
                self.send_error(503)
                return
            headers = {k: v for k, v in self.headers.items()
                       if k.lower() in ("authorization", "content-type", "accept")}
            r = httpx.request(self.command, server + self.path, content=body,
                              headers=headers)
            self.send_response(r.status_code)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(r.content)))
            self.end_headers()
            self.wfile.write(r.content)

        do_GET = do_POST = do_PUT = _any  # noqa: N815 (http.server's names)

        def log_message(self, *_: object) -> None:
            pass

    front = ThreadingHTTPServer(("127.0.0.1", 0), Front)
    front.daemon_threads = True
    thread = threading.Thread(target=front.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{front.server_address[1]}", held
    finally:
        release.set()
        front.shutdown()
        front.server_close()


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_command_stopped_by_a_signal_mid_step_revokes_its_token(
        settings: Settings, experimenter: dict[str, str], db_url: str,
        stop: signal.Signals) -> None:
    """Ctrl-C ran the revocation; SIGTERM and SIGHUP (kill, a closed terminal) ended the
    process without it, leaving a 30-day bearer token alive."""
    env = {**os.environ, "EXOSTUDY_PASSWORD": experimenter["password"],
           "PYTHONPATH": str(ROOT)}
    env.pop("EXOSTUDY_TOKEN", None)
    with running_server(settings) as url, _holding_steps(url) as (front, held):
        cli = subprocess.Popen(
            [sys.executable, "-m", "backend.hardware_cli", "--url", front,
             "--user", experimenter["username"], "status"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            wait_for(lambda: held.is_set() or cli.poll() is not None, 60,
                     "the command to log in and start its step")
            assert cli.poll() is None, cli.communicate()
            assert _bearer_tokens(db_url) == (1, 1)  # logged in: one live token
            cli.send_signal(stop)
            _, err = cli.communicate(timeout=60)
        finally:
            if cli.poll() is None:
                cli.kill()
                cli.wait()
        assert _bearer_tokens(db_url) == (1, 0), err  # made, and revoked
        assert cli.returncode == 128 + stop, err


def _bearer_tokens(db_url: str) -> tuple[int, int]:
    """(bearer tokens made, of which not revoked)."""
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        tokens = list(db.scalars(select(AuthToken).where(AuthToken.kind == "bearer")))
    engine.dispose()
    return len(tokens), sum(t.revoked_at is None for t in tokens)
