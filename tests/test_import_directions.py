"""The layers import in one direction only, exactly as docs/architecture.md draws them.

The rules are read from the document, not restated here: its mermaid diagram (which
package may import which) and its exceptions table (one module, one more import, by full
path). Imports are read from the source with `ast`, so the rules hold for code that is
imported lazily inside a function as well. Beyond the rules: the imports the source
really makes (exceptions included) form no cycle between the backend's parts, and the
bare packages hold no code.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
WEB = ("fastapi", "starlette", "uvicorn")
#: The bare packages: `from backend import x` is checked as `backend.x`.
ROOTS = ("backend", "controller")


@dataclass(frozen=True)
class Rules:
    """The document's rules: each node's module prefixes, the arrows between nodes, and
    the exceptions (importer module, imported module or package)."""

    nodes: dict[str, tuple[str, ...]]
    arrows: frozenset[tuple[str, str]]
    exceptions: frozenset[tuple[str, str]]

    def allows(self, here: str, there: str) -> bool:
        """Whether node `here` may import node `there`: the same node, an arrow, or an
        arrow to a package node that `there` lies inside (`worker --> controller` lets the
        worker import every part of `controller/`)."""
        if here == there or (here, there) in self.arrows:
            return True
        inner = self.nodes.get(there, ())
        return any(a == here and inner and all(_under(p, self.nodes[b]) for p in inner)
                   for a, b in self.arrows if b in self.nodes)

    def node_of(self, module: str) -> str | None:
        """The node whose prefix matches `module` most closely."""
        best, length = None, -1
        for node, prefixes in self.nodes.items():
            for p in prefixes:
                if _under(module, (p,)) and len(p) > length:
                    best, length = node, len(p)
        return best


def _under(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _path_module(path: str) -> str:
    """`backend/api/` -> `backend.api`, `backend/main.py` -> `backend.main`."""
    return path.rstrip("/").removesuffix(".py").replace("/", ".")


def read_rules(text: str) -> Rules:
    """Parse the diagram and the exceptions table of docs/architecture.md."""
    chart = re.search(r"```mermaid\n(.*?)```", text, re.S)
    assert chart, "docs/architecture.md has no mermaid diagram"
    nodes: dict[str, tuple[str, ...]] = {}
    arrows: set[tuple[str, str]] = set()
    for line in chart.group(1).splitlines():
        line = line.strip()
        for node, label in re.findall(r'(\w+)\["([^"]*)"\]', line):
            paths = re.findall(r"(?:backend|controller)/[\w/]*(?:\.py)?", label.split("(")[0])
            if paths:
                nodes[node] = tuple(_path_module(p) for p in paths)
        bare = re.sub(r'\["[^"]*"\]', "", line)
        if "-.-" in bare or "-->" not in bare:
            continue  # a dotted arrow is not an import
        sides = [re.findall(r"\w+", part) for part in bare.split("-->")]
        for left, right in zip(sides, sides[1:], strict=False):
            arrows.update((a, b) for a in left for b in right)
    section = text.split("### Exceptions", 1)[1].split("\n## ", 1)[0]
    exceptions = set()
    for row in section.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].startswith("`"):
            exceptions.add((cells[0].strip("`"), cells[1].strip("`")))
    return Rules(nodes, frozenset(arrows), frozenset(exceptions))


def _is_module(name: str) -> bool:
    """Whether `name` is a module or package of this tree."""
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _imports(path: Path) -> set[str]:
    """Every module `path` imports (absolute imports). `from a import b` imports `a.b`
    when that is a module of this tree (`from backend.db import audit` imports the
    audit module, not the whole package), else `a`."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                found.add(sub if _is_module(sub) else node.module)
    return found


def _modules(package: str) -> dict[str, set[str]]:
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = _imports(path)
    return out


def _third_party_rule(mod: str, target: str) -> str | None:
    """The rules the arrows cannot say: which third-party packages a layer may use."""
    if _under(mod, ("controller",)) and _under(target, ("sqlalchemy", "viser", *WEB)):
        return "the controller knows nothing of the server"
    if _under(mod, ("backend.worker",)) and _under(target, ("sqlalchemy", *WEB)):
        return "the worker process runs the controller and the device only"
    if _under(target, WEB) and not _under(mod, ("backend.api",)):
        return "only backend/api speaks HTTP"
    return None


def violations(graph: dict[str, set[str]], rules: Rules) -> tuple[list[str], set[tuple[str, str]]]:
    """Each import that breaks a rule, as `importer -> imported (rule)`; and the
    exceptions that were used."""
    bad, used = [], set()
    for mod, imported in sorted(graph.items()):
        # A bare package is a node without arrows: it may import nothing.
        here = mod if mod in ROOTS else rules.node_of(mod)
        if here is None:
            bad.append(f"{mod} (not in the document's diagram)")
            continue
        for target in sorted(imported):
            if target in ROOTS:
                continue
            excused = [e for e in rules.exceptions if e[0] == mod and _under(target, (e[1],))]
            if _under(target, ROOTS):
                there = rules.node_of(target)
                rule = (None if there is not None and rules.allows(here, there)
                        else f"no arrow {here} --> {there}")
            else:
                rule = _third_party_rule(mod, target)
            if rule is None:
                continue
            if excused:
                used.update(excused)
            else:
                bad.append(f"{mod} -> {target} ({rule})")
    return bad, used


def _acyclic(rules: Rules) -> list[str]:
    """The nodes on a cycle of arrows (a layering has none)."""
    graph = {n: {b for a, b in rules.arrows if a == n} for n in rules.nodes}
    state: dict[str, int] = {}
    cyclic: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        for m in graph.get(n, ()):
            if state.get(m) == 1:
                cyclic.append(f"{n} --> {m}")
            elif m not in state:
                visit(m)
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n)
    return cyclic


def node_imports(graph: dict[str, set[str]], rules: Rules, within: str
                 ) -> dict[str, set[str]]:
    """Which node imports which, from the imports the source really makes (exceptions
    included), between the nodes under `within` (`backend`)."""
    edges: dict[str, set[str]] = {}
    for mod, imported in graph.items():
        here = rules.node_of(mod)
        if here is None or not _under(mod, (within,)):
            continue
        for target in imported:
            there = rules.node_of(target) if _under(target, (within,)) else None
            if there is not None and there != here:
                edges.setdefault(here, set()).add(there)
    return edges


def cycle(edges: dict[str, set[str]]) -> list[str]:
    """One cycle of `edges` as the nodes along it, first one repeated at the end
    (`["lab", "live", "lab"]`); [] if there is none."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(n: str) -> list[str]:
        state[n] = 1
        path.append(n)
        for m in sorted(edges.get(n, ())):
            if state.get(m) == 1:
                return [*path[path.index(m):], m]
            if m not in state and (found := visit(m)):
                return found
        state[n] = 2
        path.pop()
        return []

    for n in sorted(edges):
        if n not in state and (found := visit(n)):
            return found
    return []


def code_in(init: Path) -> list[str]:
    """The statements of a package's `__init__.py` besides its docstring."""
    body = ast.parse(init.read_text(encoding="utf-8")).body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return [ast.unparse(node).splitlines()[0] for node in body]


def test_the_tree_keeps_the_documents_import_directions() -> None:
    rules = read_rules(DOC.read_text(encoding="utf-8"))
    graph = _modules("controller") | _modules("backend")
    assert "backend.api.deps" in graph and "controller.controllers.factory" in graph
    bad, used = violations(graph, rules)
    assert bad == []
    assert sorted(rules.exceptions - used) == [], "exceptions no import needs any more"


def test_the_backend_imports_in_one_order() -> None:
    """No two parts of the backend import each other, directly or round a loop: the
    exceptions bend the arrows, never into a cycle."""
    rules = read_rules(DOC.read_text(encoding="utf-8"))
    edges = node_imports(_modules("backend"), rules, "backend")
    assert {"study", "lab", "emgrec", "analysis", "live", "schemas", "lsl"} <= set(edges) | {
        b for bs in edges.values() for b in bs}
    assert cycle(edges) == []


def read_order(text: str, rules: Rules) -> list[set[str]]:
    """The document's package order: its nodes, rank by rank, top first (packages of
    one rank are separated by commas)."""
    found = re.search(r"^(`backend/\w+/` >.*?)\n\n", text, re.S | re.M)
    assert found, "docs/architecture.md states no package order"
    ranks = []
    for rank in found.group(1).replace("\n", " ").split(">"):
        names = re.findall(r"`(backend/\w+)/`", rank)
        ranks.append({rules.node_of(_path_module(n)) or n for n in names})
    return ranks


def downward(edges: dict[str, set[str]], ranks: list[set[str]]) -> list[str]:
    """The imports between ranked nodes that do not go down the order."""
    rank = {node: i for i, nodes in enumerate(ranks) for node in nodes}
    return sorted(f"{a} --> {b}" for a, bs in edges.items() for b in bs
                  if a in rank and b in rank and rank[a] >= rank[b])


def test_the_document_states_the_order_the_packages_import_in() -> None:
    text = DOC.read_text(encoding="utf-8")
    rules = read_rules(text)
    ranks = read_order(text, rules)
    backend_packages = {p.name for p in (ROOT / "backend").iterdir()
                        if (p / "__init__.py").is_file()}
    assert {rules.node_of(f"backend.{p}") for p in backend_packages} == set().union(*ranks)
    assert downward(node_imports(_modules("backend"), rules, "backend"), ranks) == []
    assert downward({"lab": {"live"}, "live": {"lab"}}, [{"lab"}, {"live"}]) == [
        "live --> lab"]


def test_the_packages_hold_no_code() -> None:
    """Every package's `__init__.py` is a docstring: importing a module never runs a
    re-export of its siblings (`controller.evaluation` re-exporting its figures cost
    every server start Matplotlib and SciPy)."""
    inits = sorted(p for root in ROOTS for p in (ROOT / root).rglob("__init__.py"))
    assert {ROOT / r / "__init__.py" for r in ROOTS} <= set(inits)
    assert ROOT / "controller" / "evaluation" / "__init__.py" in inits
    assert {str(p.relative_to(ROOT)): code_in(p) for p in inits if code_in(p)} == {}


def test_the_cycle_and_code_checks_can_fail(tmp_path: Path) -> None:
    edges = {"lab": {"live", "db"}, "live": {"worker"}, "worker": {"lab"}, "db": set()}
    assert cycle(edges) == ["lab", "live", "worker", "lab"]
    assert cycle({"lab": {"live"}, "live": {"db"}}) == []
    rules = read_rules(TOY)
    graph = {"backend.api.routes.trials": {"backend.study.trials"},
             "backend.study.trials": {"backend.api.errors", "backend.db.models"}}
    assert cycle(node_imports(graph, rules, "backend")) == ["api", "study", "api"]
    init = tmp_path / "__init__.py"
    init.write_text('"""Only words."""\n')
    assert code_in(init) == []
    init.write_text('"""Words."""\nfrom __future__ import annotations\nX = 1\n')
    assert code_in(init) == ["from __future__ import annotations", "X = 1"]
    real = read_rules(DOC.read_text(encoding="utf-8"))
    bad, _ = violations({"controller": {"controller.config"}, "backend": {"backend.main"}},
                        real)
    assert bad == ["backend -> backend.main (no arrow backend --> main)",
                   "controller -> controller.config (no arrow controller --> common)"]


def test_the_document_draws_a_layering() -> None:
    rules = read_rules(DOC.read_text(encoding="utf-8"))
    assert rules.nodes["api"] == ("backend.api",)
    assert rules.nodes["cli"][0] == "backend.cli"
    assert ("study", "analysis") in rules.arrows and ("analysis", "study") not in rules.arrows
    assert ("worker", "controller") in rules.arrows
    assert not [a for a in rules.arrows if a[0] == "controller"]
    assert {b for a, b in rules.arrows if a == "worker"} == {"schemas", "controller"}
    assert _acyclic(rules) == []
    # The controller's parts: the device sits at the bottom, the simulator above it.
    assert ("sim", "device") in rules.arrows and ("device", "sim") not in rules.arrows
    assert not [b for a, b in rules.arrows if a == "device"]
    named = {m for pair in rules.exceptions for m in pair}
    assert all("." in m or m in WEB for m in named), "exceptions name full module paths"


TOY = """
```mermaid
flowchart TD
    browser["frontend/"] -. "HTTP" .-> api
    api["backend/api/"] --> study & db
    study["backend/study/"] --> db
    worker["backend/worker/"] --> controller
    db["backend/db/"]
    controller["controller/"]
```
### Exceptions

| module | may also import | why |
|---|---|---|
| `backend.db.models` | `backend.study.audit` | a toy exception |
| `backend.study.old` | `backend.api.errors` | no longer needed |
"""


def test_each_rule_can_fail() -> None:
    rules = read_rules(TOY)
    assert rules.arrows == {("api", "study"), ("api", "db"), ("study", "db"),
                            ("worker", "controller")}
    graph = {
        "controller.controllers.umc": {"backend.db.models", "sqlalchemy"},
        "backend.worker.process": {"backend.db.engine", "controller.runner.loop"},
        "backend.study.audit": {"fastapi", "backend.db.models"},
        "backend.study.trials": {"backend.api.errors"},
        "backend.db.models": {"backend.study.audit", "backend.study.access"},
        "backend.api.routes.trials": {"fastapi", "backend.study.trials", "backend.db"},
        "backend.guide": {"backend.api"},
    }
    bad, used = violations(graph, rules)
    assert bad == [
        "backend.db.models -> backend.study.access (no arrow db --> study)",
        "backend.guide (not in the document's diagram)",
        "backend.study.audit -> fastapi (only backend/api speaks HTTP)",
        "backend.study.trials -> backend.api.errors (no arrow study --> api)",
        "backend.worker.process -> backend.db.engine (no arrow worker --> db)",
        "controller.controllers.umc -> backend.db.models (no arrow controller --> db)",
        "controller.controllers.umc -> sqlalchemy (the controller knows nothing of the server)",
    ]
    assert used == {("backend.db.models", "backend.study.audit")}
    assert rules.exceptions - used == {("backend.study.old", "backend.api.errors")}
    assert _acyclic(Rules(rules.nodes, rules.arrows | {("db", "api")}, frozenset()))


def test_an_arrow_to_a_package_covers_its_parts() -> None:
    rules = read_rules(TOY.replace('    controller["controller/"]', '''    controller["controller/"]
    sim["controller/sim/"] --> device
    device["controller/device/"]'''))
    graph = {
        "backend.worker.process": {"controller.sim.plant", "controller.device.base"},
        "controller.sim.plant": {"controller.device.base"},
        "controller.device.base": {"controller.sim.plant"},
    }
    bad, _ = violations(graph, rules)
    assert bad == ["controller.device.base -> controller.sim.plant (no arrow device --> sim)"]
