"""The layers import in one direction only (docs/architecture.md draws them).

Read from the source with `ast`, so the rules hold for code that is imported lazily
inside a function as well. A rule broken here is a design change: change the diagram
first, then this list.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WEB = ("fastapi", "starlette", "uvicorn")
#: Modules that may use the web framework outside backend/api: the application factory,
#: the command line (serves it with uvicorn), the console's page shells, the 3D viewer's
#: page and WebSocket, and the virtual study's local server (a separate small app).
WEB_OUTSIDE_API = {"backend.main", "backend.cli", "backend.console_pages", "viewer",
                   "local_server"}


def _imports(path: Path) -> set[str]:
    """Every module `path` imports (absolute imports; with `from a import b`, both `a`
    and `a.b`, since `b` may be a module)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
    return found


def _modules(package: str) -> dict[str, set[str]]:
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = _imports(path)
    return out


def _under(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def violations(graph: dict[str, set[str]]) -> list[str]:
    """Each import that breaks a rule, as `importer -> imported (rule)`."""
    bad = []
    for mod, imported in graph.items():
        for target in sorted(imported):
            rule = None
            if _under(mod, ("controller",)) and _under(
                    target, ("backend", "sqlalchemy", "viser", *WEB)):
                rule = "the controller knows nothing of the server"
            elif _under(mod, ("backend.worker",)) and _under(
                    target, ("backend", "sqlalchemy", *WEB)) \
                    and not _under(target, ("backend.worker", "backend.schemas")):
                # The schemas: the reports it sends have one typed definition, shared
                # with the server.
                rule = "the worker process runs the controller and the device only"
            elif _under(target, WEB) and not _under(mod, ("backend.api",)) \
                    and mod not in WEB_OUTSIDE_API \
                    and mod.rsplit(".", 1)[-1] not in WEB_OUTSIDE_API:
                rule = "only backend/api speaks HTTP"
            elif _under(target, ("backend.api",)) and not _under(mod, ("backend.api",)) \
                    and mod not in WEB_OUTSIDE_API \
                    and mod.rsplit(".", 1)[-1] not in WEB_OUTSIDE_API:
                rule = "services do not call the routes"
            elif _under(mod, ("backend.db", "backend.core", "backend.schemas")) and _under(
                    target, ("backend.study", "backend.analysis", "backend.live",
                             "backend.live.runtime", "backend.api")):
                rule = "storage, settings and schemas sit below the services"
            if rule:
                bad.append(f"{mod} -> {target} ({rule})")
    return bad


def test_the_tree_keeps_the_import_directions() -> None:
    graph = _modules("controller") | _modules("backend")
    assert "backend.api.deps" in graph and "controller.factory" in graph
    assert violations(graph) == []


def test_each_rule_can_fail() -> None:
    graph = {
        "controller.umc": {"backend.db.models"},
        "backend.worker.process": {"backend.db.engine"},
        "backend.study.audit": {"fastapi"},
        "backend.analysis.results": {"backend.api.errors", "backend.study.audit"},
        "backend.db.models": {"backend.study.access"},
        "backend.api.routes.trials": {"fastapi", "backend.study.trials"},  # allowed
        "backend.live.viewer": {"fastapi", "backend.api.deps"},  # allowed
    }
    rules = [v.split("(")[1] for v in violations(graph)]
    assert rules == [
        "the controller knows nothing of the server)",
        "the worker process runs the controller and the device only)",
        "only backend/api speaks HTTP)",
        "services do not call the routes)",
        "storage, settings and schemas sit below the services)",
    ]
