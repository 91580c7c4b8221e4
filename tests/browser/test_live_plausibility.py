"""The live page shows implausible samples: a device process with faulty encoders, the
real server and worker, the page in Chromium."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from controller.device.auth import create_key
from tests.browser.login_page import log_in_through
from tests.faults.device_rig import model_device_process
from tests.faults.test_sample_faults import serve_glitchy
from tests.live_server import running_server
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow


def test_the_strip_names_implausible_samples(
    settings: Settings, experimenter: dict[str, str], page: Any, tmp_path: Path
) -> None:
    key_file = tmp_path / "device.key"
    create_key(key_file)
    port = free_udp_port()
    live = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": False,
        "device_address": f"127.0.0.1:{port}", "device_key_file": key_file,
        "run_dir": tmp_path})
    with model_device_process(serve_glitchy, port, str(key_file), 1, "squat-sequence"), \
            running_server(live) as url:
        log_in_through(page, url, "/live", experimenter)
        # About one sample in twenty is a glitch: the strip counts them and, while one
        # is the latest tick, names why.
        wait_for(lambda: page.evaluate("() => window.exostudyLive?.strip?.implausible ?? 0")
                 >= 20, 90, "the strip to count 20 implausible ticks")
        # The reason is shown only while an implausible tick is the latest one, so read
        # the text in the same evaluation that finds it shown.
        shown: list[str] = []

        def reason_shown() -> bool:
            t = page.evaluate("""() => {
                const e = document.querySelector('#strip-implausible');
                return e && !e.hidden ? e.textContent : ''; }""")
            if t:
                shown.append(t)
            return bool(t)

        wait_for(reason_shown, 60, "the strip to name an implausible sample")
        text = shown[-1]
        health = httpx.get(f"{url}/api/health").json()
    assert text.startswith("implausible sample: ")
    reasons = {"angle jump", "acceleration", "out of range", "hip velocity"}
    assert any(r in text for r in reasons), text
    assert health["device"]["implausible_samples"] > 0
    assert health["device"]["link_drops"]["auth"] == 0
