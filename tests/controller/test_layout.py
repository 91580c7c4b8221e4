"""`controller/` is laid out as docs/architecture.md describes it: no two modules share a
name, every subpackage says what it is, and `tests/controller/` mirrors it."""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "controller"


def _modules() -> list[Path]:
    return [p for p in PACKAGE.rglob("*.py") if p.name != "__init__.py"]


def test_no_two_modules_share_a_name() -> None:
    names = Counter(p.stem for p in _modules())
    packages = {p.name for p in PACKAGE.rglob("*") if (p / "__init__.py").is_file()}
    assert [n for n, k in names.items() if k > 1] == []
    assert sorted(names.keys() & packages) == [], "a module named like a package"


def test_each_subpackage_says_what_it_is() -> None:
    for init in sorted(PACKAGE.glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and len(doc) > 40, f"{init.relative_to(ROOT)} has no docstring"


def test_the_tests_mirror_the_subpackages() -> None:
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    tests = {p.parent.name for p in (ROOT / "tests" / "controller").glob("*/__init__.py")}
    assert subpackages == tests
