"""Nothing outside a controller's own module decides by its name.

What a controller needs (models, a calibration), whether it estimates intent, its label
and colour and where it enters a trial plan are declared in its registration
(`controller.controllers.registry.Registration`); code elsewhere asks the registry. Read from the
source with `ast`: a comparison (`==`, `!=`, `in`, `not in`) with a registered name as a
literal, anywhere in `controller/` or `backend/` outside the module that registers that
name, fails here.
"""

from __future__ import annotations

import ast
from pathlib import Path

from controller.controllers import registry

ROOT = Path(__file__).resolve().parents[1]


def _literals(node: ast.expr) -> list[str]:
    """The string literals a comparison operand spells: a constant, or the members of a
    tuple, list or set display."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [s for e in node.elts for s in _literals(e)]
    return []


def name_comparisons(source: str, module: str, owners: dict[str, str]) -> list[str]:
    """Each comparison in `source` with a controller name that `module` does not
    register, as `line: name`. `owners`: controller name -> its registering module."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Compare):
            continue
        for operand in (node.left, *node.comparators):
            for s in _literals(operand):
                if s in owners and owners[s] != module:
                    found.append(f"{node.lineno}: {s!r}")
    return found


def _owners() -> dict[str, str]:
    return {n: registry.get(n).build.__module__ for n in registry.names()}


def test_no_controller_name_is_compared_outside_its_module() -> None:
    owners = _owners()
    assert set(owners) >= {"umc", "eumc", "pec", "none"}
    assert owners["eumc"] == "controller.controllers.eumc"
    bad = []
    for package in ("controller", "backend"):
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT)
            module = ".".join(rel.with_suffix("").parts)
            bad += [f"{rel}:{hit}" for hit in
                    name_comparisons(path.read_text(encoding="utf-8"), module, owners)]
    assert bad == [], ("compare capabilities (controller.controllers.registry), not names:\n"
                       + "\n".join(bad))


def test_the_scan_finds_each_form_of_comparison() -> None:
    owners = {"eumc": "controller.controllers.eumc", "none": "controller.controllers.passthrough"}
    source = "\n".join([
        'if name == "eumc": pass',
        'if "eumc" != c: pass',
        'if c in ("pec", "eumc"): pass',
        'if c not in {"none"}: pass',
        'if a < b: pass',  # no literal
        'if c == "walking": pass',  # not a controller name
        'x = "eumc"',  # not a comparison
    ])
    assert name_comparisons(source, "backend.live.runtime", owners) == [
        "1: 'eumc'", "2: 'eumc'", "3: 'eumc'", "4: 'none'"]
    # The registering module itself may spell its own name.
    assert name_comparisons('if n == "eumc": pass', "controller.controllers.eumc", owners) == []
