"""The hardware bring-up page in Chromium against the UDP device simulator the server
spawns: encoder zero, a solenoid pulse and the watchdog test, each result in its row."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from backend.core.config import Settings
from tests.browser.login_page import log_in_through
from tests.live_server import running_server
from tests.polling import free_udp_port, wait_for

pytestmark = [pytest.mark.browser, pytest.mark.slow]


@pytest.fixture
def udp_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    """The app with its worker and the device simulator process, wearer standing."""
    with running_server(settings.model_copy(update={
            "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
            "device_address": f"127.0.0.1:{free_udp_port()}",
            "device_script": "standing"})) as url:
        yield url


def _run(page: Any, step: str) -> str:
    """Run one step from its row; returns its result cell's text once it has one and the
    step's action has ended (its button enabled again): the action writes the shared
    message line after the result, and a next click must not race that write."""
    page.click(f"#run-{step}")
    page.wait_for_selector(f"#step-table tr[data-step='{step}'][data-passed]", timeout=120_000)
    page.wait_for_selector(f"#run-{step}:enabled", timeout=30_000)
    return page.text_content(f"#step-table tr[data-step='{step}'] .result") or ""


def test_zero_pulse_and_watchdog_from_the_page(udp_server: str, page: Any,
                                               experimenter: dict[str, str]) -> None:
    failed: list[str] = []
    page.on("response", lambda r: failed.append(f"{r.status} {r.url}")
            if r.status >= 400 and "/guide/" not in r.url else None)
    log_in_through(page, udp_server, "/hardware", experimenter)
    page.wait_for_selector("body[data-ready='true']")
    assert "udp-sim (simulated)" in (page.text_content("#device") or "")
    assert "not run" in (page.text_content("#step-table tr[data-step='zero'] .result") or "")

    # The steps belong to the device on the link: they wait until it has proved its
    # identity (a CHALLENGE answered), which can come after the health turns ok.
    def joined() -> bool:
        return bool(page.evaluate("fetch('/api/health').then(r => r.json())"
                                  ".then(h => h.status === 'ok' && !!h.device.identity)"))

    wait_for(joined, 60, "the device to prove its identity")
    page.reload()
    page.wait_for_selector("body[data-ready='true']")
    zero = _run(page, "zero")
    assert zero.startswith("passed") and "zeroed over 200 still samples" in zero
    values = page.text_content("#step-table tr[data-step='zero'] .values") or ""
    assert "offsets: [" in values

    # Without the confirmation the page refuses before asking the server.
    page.click("#run-pulse_left")
    page.wait_for_selector("#step-msg.msg-bad")
    assert "nobody wears the exoskeleton" in (page.text_content("#step-msg") or "")
    assert page.get_attribute("#step-table tr[data-step='pulse_left']", "data-passed") is None

    page.check("#nobody-wearing")
    pulse = _run(page, "pulse_left")
    assert pulse.startswith("passed") and "SOLENOID_LEFT came on and went off" in pulse
    # The pulse's coil cools down first (duty cycle at most 25 %: off three times its
    # on-time); the server would answer 409 to an early run.
    def cooled() -> bool:
        waits = page.evaluate("fetch('/api/hardware').then(r => r.json())"
                              ".then(h => Object.values(h.cooldown_s))")
        return not any(s > 0 for s in waits)

    wait_for(cooled, 10, "the left coil to cool down")
    dog = _run(page, "watchdog")
    assert "released" in dog and "after the sample the last command answered (device" in dog
    dog_values = page.text_content("#step-table tr[data-step='watchdog'] .values") or ""
    assert "release_ms:" in dog_values and "solenoid_seen: true" in dog_values
    assert failed == []
