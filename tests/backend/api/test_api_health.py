"""The HTTP surface without a worker: health says so, pages and vendor files are served."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from tests.login import log_in


def test_health_without_a_worker_is_degraded(settings: Settings) -> None:
    with TestClient(create_app(settings)) as client:
        body = client.get("/api/health").json()
    assert body["status"] == "degraded"
    assert body["worker"]["alive"] is False
    assert body["worker"]["pid"] is None
    assert body["device"]["alive"] is False
    assert body["device"]["kind"] == "sim"


def test_live_page_and_uplot_are_served_locally(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    with TestClient(create_app(settings)) as client:
        anonymous = client.get("/live", follow_redirects=False)
        assert anonymous.status_code == 303
        assert anonymous.headers["location"] == "/login?next=/live"
        log_in(client, experimenter)
        page = client.get("/live")
        assert page.status_code == 200
        assert "/vendor/uplot/uPlot.min.css" in page.text
        assert "http" not in page.text.replace("http-equiv", "")  # nothing from the internet
        js = client.get("/vendor/uplot/uPlot.esm.js")
        assert js.status_code == 200 and "export" in js.text
        assert client.get("/", follow_redirects=False).headers["location"] == "/live"


def test_login_page_is_served_without_a_login(settings: Settings) -> None:
    with TestClient(create_app(settings)) as client:
        page = client.get("/login")
    assert page.status_code == 200 and "/api/auth/login" not in page.text
    assert "/static/login.js" in page.text


def test_unknown_controller_is_refused_with_its_name(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    with TestClient(create_app(settings)) as client:
        assert client.post("/api/worker/controller", json={"name": "pec"}).status_code == 401
        log_in(client, experimenter)
        r = client.post("/api/worker/controller", json={"name": "telepathy"})
    assert r.status_code == 422
    assert "telepathy" in r.json()["detail"]


def test_settings_validate_the_device_address() -> None:
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="HOST:PORT"):
        Settings(device_address="localhost", _env_file=None)  # type: ignore[call-arg]
    s = Settings(device_address="127.0.0.1:6000", _env_file=None)  # type: ignore[call-arg]
    assert s.device_host_port == ("127.0.0.1", 6000)


def test_settings_come_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EXOSTUDY_PORT", "8123")
    monkeypatch.setenv("EXOSTUDY_DEVICE_KIND", "udp")
    s = Settings(_env_file=None)  # type: ignore[call-arg]
    assert (s.port, s.device_kind) == (8123, "udp")
