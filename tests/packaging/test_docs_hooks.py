"""The guide's build hook: benchmark tables come from the benchmarks' result files, and
no script from another site is added to the pages."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _hooks() -> ModuleType:
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "tools/docs/hooks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def hooks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    module = _hooks()
    monkeypatch.setattr(module, "RESULTS", tmp_path)
    (tmp_path / "demo.json").write_text(json.dumps({
        "name": "demo", "command": "bench/bench_demo.py --n 3",
        "measured": "2026-01-02 03:04 UTC", "load_average": {"before": 0.5, "after": 1.5},
        "cores": 2, "python": "3.11.7", "columns": ["what", "time (us)"],
        "rows": [["a | b", "1.25"], ["c", "2.50"]], "note": "Median of 3."}))
    return module


def test_a_marker_line_becomes_the_recorded_table(hooks: Any) -> None:
    page = "Intro naming `<!-- bench: demo -->` in prose.\n\n<!-- bench: demo -->\n\nEnd.\n"
    out = hooks.on_page_markdown(page)
    assert out.startswith("Intro naming `<!-- bench: demo -->` in prose.")
    assert "| what | time (us) |\n| --- | --- |\n| a \\| b | 1.25 |\n| c | 2.50 |" in out
    assert ("`bench/bench_demo.py --n 3`, 2026-01-02 03:04 UTC, 2 cores, load average 0.5 "
            "before and 1.5 after, Python 3.11.7 (from `bench/results/demo.json`). "
            "Median of 3.") in out
    assert out.rstrip().endswith("End.")


def test_a_marker_without_its_file_fails_the_build(hooks: Any) -> None:
    with pytest.raises(FileNotFoundError, match="missing"):
        hooks.on_page_markdown("<!-- bench: missing -->\n")


def test_no_polyfill_from_another_site_survives() -> None:
    class Config(dict[str, Any]):
        extra: dict[str, Any]

    config = Config()
    config.extra = {"polyfills": ["https://unpkg.com/iframe-worker/shim", "local/shim.js"]}
    assert _hooks().on_config(config).extra["polyfills"] == ["local/shim.js"]


def test_every_recorded_result_renders() -> None:
    """The committed result files are well formed (the guide's build renders each)."""
    hooks = _hooks()
    files = sorted((ROOT / "bench" / "results").glob("*.json"))
    assert files
    for path in files:
        table = hooks.render(path.stem)
        doc = json.loads(path.read_text())
        assert table.count("\n|") == len(doc["rows"]) + 1, path.name
