"""MkDocs hook of the guide: benchmark tables from the benchmarks' own result files.

A page writes `<!-- bench: NAME -->` on a line of its own where a table belongs; the
build puts there the table of `bench/results/NAME.json` (written by the benchmark, see
bench/record.py) with the command and the conditions it was measured under. A marker
without its file fails the build, so a page never shows a table that no benchmark wrote.

The offline plugin adds a script from a CDN (a web-worker shim for pages opened from
disk); ExoStudy loads nothing from the internet, so the hook takes it out again. Served
(at /guide by the app, or by `mkdocs serve`), search runs in the theme's own worker;
opened from disk, navigation works and search does not (browsers start no workers from
`file://`).

After the build, the theme's files the guide never loads are removed (source maps, and
the search's stemmers for languages other than English), which halves what the wheel
carries.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any

from mkdocs.plugins import event_priority

RESULTS = Path(__file__).resolve().parents[2] / "bench" / "results"
#: A marker is a line of its own (so prose can name the marker in backticks).
_MARKER = re.compile(r"^<!--\s*bench:\s*([\w-]+)\s*-->[ \t]*$", re.M)


def _cell(value: object) -> str:
    return str(value).replace("|", "\\|")


def render(name: str) -> str:
    """The Markdown table of one result file, with its provenance line."""
    path = RESULTS / f"{name}.json"
    if not path.is_file():
        raise FileNotFoundError(f"<!-- bench: {name} -->: no {path}; run the benchmark "
                                "that writes it")
    doc: dict[str, Any] = json.loads(path.read_text())
    lines = ["| " + " | ".join(_cell(c) for c in doc["columns"]) + " |",
             "|" + " --- |" * len(doc["columns"])]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in doc["rows"]]
    load = doc["load_average"]
    prov = (f"`{doc['command']}`, {doc['measured']}, {doc['cores']} cores, load average "
            f"{load['before']} before and {load['after']} after, Python {doc['python']} "
            f"(from `bench/results/{name}.json`).")
    if doc.get("note"):
        prov += f" {doc['note']}"
    return "\n".join(lines) + "\n\n" + prov + "\n"


@event_priority(-100)  # after the offline plugin added its shim
def on_config(config: Any, **_: Any) -> Any:
    """Remove every polyfill that would load from another site."""
    polyfills = config.extra.get("polyfills", [])
    config.extra["polyfills"] = [p for p in polyfills if "://" not in str(p)]
    return config


def on_page_markdown(markdown: str, **_: Any) -> str:
    """Replace every benchmark marker of a page with its table."""
    return _MARKER.sub(lambda m: render(m.group(1)), markdown)


def on_post_build(config: Any, **_: Any) -> None:
    """Drop the theme's source maps and non-English search stemmers (never loaded)."""
    site = Path(config["site_dir"])
    for path in site.rglob("*.map"):
        path.unlink()
    shutil.rmtree(site / "assets" / "javascripts" / "lunr", ignore_errors=True)
