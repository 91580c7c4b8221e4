"""No module of `controller/` imports another module's private (`_`-prefixed) names: what
one part uses of another has a public name in the module it belongs to (the compiled tick
reads the plant's link-angle columns `OUTPUT` and `CAM`; the UMC runs the onset and
intent kernels `bank_kernel` and `intent_kernel`)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def private_imports(source: str) -> list[str]:
    """`module.name` for each private name imported from a module of this tree."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] in ("controller", "backend"):
            found += [f"{node.module}.{a.name}" for a in node.names
                      if a.name.startswith("_") and not a.name.startswith("__")]
    return found


def test_no_part_of_the_controller_imports_private_names() -> None:
    found = {str(p.relative_to(ROOT)): private_imports(p.read_text(encoding="utf-8"))
             for p in sorted((ROOT / "controller").rglob("*.py"))}
    assert {path: names for path, names in found.items() if names} == {}


def test_the_check_sees_a_private_import() -> None:
    assert private_imports("from controller.sim.plant import _CAM, plant_step") == [
        "controller.sim.plant._CAM"]
    assert private_imports("from controller.sim.plant import CAM\nimport numpy._core") == []
    assert private_imports("from numpy import _pytesttester") == []
